"""``python -m arduinobot.cli``: the `arduinobot` command."""

import sys

from arduinobot.cli.main import main

sys.exit(main())
