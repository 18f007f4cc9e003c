"""``python -m uwhl_rs``: the same as the ``uwhl`` command (see :mod:`uwhl_rs.cli`)."""

import sys

from uwhl_rs.cli import main

if __name__ == "__main__":
    sys.exit(main())
