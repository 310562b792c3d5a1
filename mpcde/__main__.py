"""``python -m mpcde`` runs the command line."""

from mpcde.cli import main

if __name__ == "__main__":
    raise SystemExit(main())
