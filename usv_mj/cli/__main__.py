"""``python -m usv_mj.cli``: the program ``usv-mj`` (:func:`usv_mj.cli.main.entry`)."""

import sys

from usv_mj.cli.main import entry

sys.exit(entry())
