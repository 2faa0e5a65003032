"""``python -m refine.cli``: the same as the ``nonrigid`` command."""

import sys

from refine.cli.main import main

sys.exit(main())
