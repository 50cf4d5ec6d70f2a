"""Golden numbers: metrics checked into ``tests/golden/*.json`` and compared with an allowed drift.

Run ``pytest --regen-goldens`` to rewrite them deliberately (then review and commit the diff).
A missing golden file is an error unless ``--regen-goldens`` is given: a golden is never created
silently by a normal test run.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

GOLDEN_DIR = Path(__file__).resolve().parent / "golden"


def _flatten(d, prefix=""):
    out = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(_flatten(v, key + "."))
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            out[key] = float(v)
    return out


class Goldens:
    """Compare (or, when regenerating, write) named dicts of numbers."""

    def __init__(self, regenerate: bool):
        self.regenerate = regenerate

    def check(self, name: str, values: dict, *, rtol: float, atol: float) -> None:
        """Assert every number in ``values`` is within ``atol + rtol·|golden|`` of ``golden/<name>.json``.

        Nested dicts are flattened to dotted keys; non-numbers are ignored. NaN must stay NaN.
        """
        path = GOLDEN_DIR / f"{name}.json"
        flat = _flatten(values)
        if self.regenerate:
            GOLDEN_DIR.mkdir(exist_ok=True)
            tmp = path.with_suffix(".json.tmp")
            tmp.write_text(json.dumps(flat, indent=1, sort_keys=True) + "\n")
            tmp.replace(path)
            return
        if not path.exists():
            raise AssertionError(f"no golden file {path}; run pytest --regen-goldens to create it")
        golden = json.loads(path.read_text())
        missing = sorted(set(golden) - set(flat))
        assert not missing, f"{name}: metrics missing from the run: {missing}"
        bad = []
        for key, ref in golden.items():
            got = flat[key]
            if ref is None or (isinstance(ref, float) and math.isnan(ref)):
                if not math.isnan(got):
                    bad.append(f"{key}: golden NaN, got {got:.6g}")
                continue
            if not abs(got - ref) <= atol + rtol * abs(ref):
                bad.append(f"{key}: golden {ref:.6g}, got {got:.6g} (allowed ±{atol + rtol * abs(ref):.3g})")
        assert not bad, f"{name} drifted from tests/golden/{name}.json:\n  " + "\n  ".join(bad)
