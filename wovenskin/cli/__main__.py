"""``python -m wovenskin.cli``: the command line."""

from wovenskin.cli import main

main()
