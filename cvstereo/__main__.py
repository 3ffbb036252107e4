"""``python -m cvstereo``: the command-line interface."""

from cvstereo.cli import main

raise SystemExit(main())
