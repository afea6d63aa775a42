"""``python -m legbench``: the same as the ``legbench`` command."""

import sys

from legbench.cli import entry

if __name__ == "__main__":  # the pool's workers import the main module again: they must not run the command
    sys.exit(entry())
