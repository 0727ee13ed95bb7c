"""``python -m hybridbrdf.cli``: the ``hbrdf`` command."""

import sys

from hybridbrdf.cli import main

sys.exit(main())
