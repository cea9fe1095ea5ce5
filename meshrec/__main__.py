"""``python -m meshrec``: the same command line as the ``meshrec`` console script."""

import sys

from meshrec.app.cli import main

if __name__ == "__main__":
    sys.exit(main())
