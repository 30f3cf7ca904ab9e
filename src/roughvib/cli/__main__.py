"""``python -m roughvib.cli``: the command-line interface."""

import sys

from roughvib.cli import main

if __name__ == "__main__":  # importing the module (as the docs build does) runs nothing
    sys.exit(main())
