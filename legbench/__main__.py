"""``python -m legbench``: the same as the ``legbench`` command."""

import sys

from legbench.cli import entry

sys.exit(entry())
