"""``python -m pipeline.cli``: the ``dance3d`` command."""

import sys

from pipeline.cli.app import main

sys.exit(main())
