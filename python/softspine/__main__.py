"""``python -m softspine``: the command line (see ``softspine.cli``)."""

import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main())
