"""``python -m aoass_env.localization LOGDIR``: see :mod:`aoass_env.localization.cli`."""

import sys

from aoass_env.localization.cli import main

sys.exit(main())
