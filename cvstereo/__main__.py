"""``python -m cvstereo``: the command-line interface."""

from cvstereo.cli import main

if __name__ == "__main__":
    raise SystemExit(main())
