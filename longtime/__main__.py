"""`python -m longtime ...` is the `longtime` command."""
import sys

from longtime.commands.cli import main

sys.exit(main())
