"""``python -m pronet.cli``: the ``pronet`` command."""

from pronet.cli import main

raise SystemExit(main())
