"""``python -m esoarm`` runs the command line (same as the ``esoarm`` command)."""

from esoarm.cli import main

if __name__ == "__main__":
    main()
