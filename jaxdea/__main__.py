"""``python -m jaxdea``: the ``jaxdea`` command line (see :mod:`jaxdea.apps.cli`)."""

import sys

from .apps.cli import main

sys.exit(main())
