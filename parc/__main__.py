"""``python -m parc``: the `parc` command, for an environment whose scripts are not on the PATH."""
import sys

from .console import main

if __name__ == "__main__":
    sys.exit(main())
