"""``python -m sweep_core.cli``: the ``sweep`` command."""
import sys

from sweep_core.cli import main

sys.exit(main())
