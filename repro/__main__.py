"""``python -m repro COMMAND ...``: the same as the ``defocus-repro`` console script."""

import sys

from repro._cli import console_main

if __name__ == "__main__":
    sys.exit(console_main())
