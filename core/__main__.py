"""``python -m lagrangian``: the same as the ``lagrangian`` command."""

import sys

from .cli import main

sys.exit(main())
