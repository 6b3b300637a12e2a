"""`python -m longtime ...` is the `longtime` command."""
import sys

from longtime.cli import main

sys.exit(main())
