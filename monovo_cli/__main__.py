from monovo_cli.cli import main

main()
