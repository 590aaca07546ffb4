"""``python -m ssbench``: the same as the ``ssbench`` command."""
from .cli import main

raise SystemExit(main())
