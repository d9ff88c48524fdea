"""``python -m jaxdea``: the ``jaxdea`` command line (see :mod:`jaxdea.cli`)."""

import sys

from .cli import main

sys.exit(main())
