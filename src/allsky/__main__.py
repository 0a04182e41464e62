"""Allow ``python -m allsky``."""

from allsky.apps.cli import main

raise SystemExit(main())
