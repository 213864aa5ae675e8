"""``python -m lagrangian``: the same as the ``lagrangian`` command (exit status as :func:`lagrangian.cli.main`)."""

import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main())
