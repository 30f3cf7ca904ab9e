"""``python -m roughvib.cli``: the command-line interface."""

import sys

from roughvib.cli import main

sys.exit(main())
