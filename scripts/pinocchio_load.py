#!/usr/bin/env python3
"""Loads URDF files in Pinocchio, as a user of graybox's export would: each must load (its
reader refuses, for one, a negative friction: "min_dry_friction greater than
max_dry_friction"), and every joint's damping and friction must be ≥ 0. Prints one JSON line
per file; exits 1 when any file fails. Offline, with Pinocchio installed
(`pip install pin==4.1.0`):

    graybox export-urdf --model m.gbx --out r.urdf
    python scripts/pinocchio_load.py r.urdf
"""

import json
import sys

import numpy as np
import pinocchio as pin


def check(path: str) -> dict:
    try:
        model = pin.buildModelFromUrdf(path)
    except Exception as e:  # Pinocchio raises plain exceptions from its reader
        return {"file": path, "loads": False, "error": str(e)}
    data = model.createData()
    q = pin.neutral(model)
    out = {
        "file": path,
        "loads": True,
        "joints": [model.names[i] for i in range(1, model.njoints)],
        "damping": model.damping.tolist(),
        "friction": model.friction.tolist(),
        "mass": pin.computeTotalMass(model, data),
        "g_neutral": pin.computeGeneralizedGravity(model, data, q).tolist(),
    }
    out["ok"] = bool(np.all(model.damping >= 0) and np.all(model.friction >= 0))
    return out


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    failed = False
    for path in sys.argv[1:]:
        r = check(path)
        print(json.dumps(r))
        failed |= not (r["loads"] and r["ok"])
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
