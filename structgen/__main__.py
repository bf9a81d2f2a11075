import sys

from structgen.cli import main

# Guarded: worker processes started with "spawn" import the main module, and must not run the command again.
if __name__ == "__main__":
    sys.exit(main())
