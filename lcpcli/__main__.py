"""``python -m lcpcli`` runs the command-line interface."""

from lcpcli.cli import main

if __name__ == "__main__":
    main()
