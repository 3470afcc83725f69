"""`python -m studies`: the `rig-study` command."""

from studies.cli import main

raise SystemExit(main())
