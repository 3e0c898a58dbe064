"""``python -m planefuse``: the same as the ``planefuse`` console script."""

from planefuse.cli import main

main()
