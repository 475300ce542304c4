"""``python -m ifc_spg.cli VERB ...``: the same as ``ifc-spg VERB ...``."""

import sys

from ifc_spg.cli import main

sys.exit(main())
