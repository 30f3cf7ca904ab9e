"""``python -m roughvib``: the command-line interface (as the ``roughvib`` console script)."""

import sys

from roughvib.cli import main

sys.exit(main())
