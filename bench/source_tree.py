"""Another source tree of ext_sense on ``PYTHONPATH``: the benchmarks' ``--baseline``.

Before/after figures must be taken side by side in one run (the shared machine's load moves
by the minute), so a benchmark runs the same measurement on an older copy of ``src/`` too:
its package directories go first on ``PYTHONPATH`` of the processes it starts, shadowing the
venv's editable installs (the messages stay the venv's).
"""

from __future__ import annotations

import os
from pathlib import Path


def baseline_path(root: Path) -> str:
    """``PYTHONPATH`` putting the package directories of the source tree ``root`` first."""
    dirs = [str(p) for p in sorted(root.resolve().glob("ext_sense*")) if (p / p.name).is_dir()]
    if not dirs:
        raise SystemExit(f"--baseline {root}: no package directories there")
    return os.pathsep.join(dirs)
