"""``python -m navbench ...``: the ``navbench`` command, also as torchrun's ``-m navbench`` target."""

import sys

from navbench.cli import main

if __name__ == "__main__":
    sys.exit(main())
