"""``python -m engine``: the engine process (started by the studio)."""

from engine.process import main

raise SystemExit(main())
