"""``python -m monovo_cli``: the ``monovo`` command line."""

from monovo_cli.cli import main

main()
