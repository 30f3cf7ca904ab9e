"""``python -m roughvib``: the command-line interface (as the ``roughvib`` console script)."""

import sys

from roughvib.cli import main

if __name__ == "__main__":  # importing the module (as the docs build does) runs nothing
    sys.exit(main())
