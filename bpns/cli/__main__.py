"""``python -m bpns.cli``: the same as the ``bpns`` console script."""

import sys

from bpns.cli import main

sys.exit(main())
