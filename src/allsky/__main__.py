"""Allow ``python -m allsky``."""

from allsky.cli import main

raise SystemExit(main())
