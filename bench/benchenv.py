"""What a bench that runs one process per core sets before numpy loads: one
BLAS thread per process, and host/, tests/ (helpers) and bench/ on the import
path.  Import it before numpy: ``import benchenv``."""
from __future__ import annotations

import os
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

ROOT = Path(__file__).resolve().parent.parent
for _sub in ("host", "tests", "bench"):
    sys.path.insert(0, str(ROOT / _sub))
