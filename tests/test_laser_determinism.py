"""Identical input gives identical DXF bytes, also across processes and string hash seeds."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys

import fabkit
from fabkit.writers.dxf import sheet_dxf
from fabkit.fab.laser_plan import laser_plan

from conftest import TEMPLATES

_CODE = """
import hashlib, fabkit
from fabkit.writers.dxf import sheet_dxf
from fabkit.fab.laser_plan import laser_plan
plan = laser_plan(fabkit.load_template({path!r}), {{"laser": {{"flavour": {flavour!r}}}}})
print(hashlib.sha256(b"".join(sheet_dxf(s, plan, len(plan.sheets)) for s in plan.sheets)).hexdigest())
"""


def _digest_here(path, flavour):
    plan = laser_plan(fabkit.load_template(path), {"laser": {"flavour": flavour}})
    data = b"".join(sheet_dxf(s, plan, len(plan.sheets)) for s in plan.sheets)
    return hashlib.sha256(data).hexdigest()


def test_same_bytes_under_different_hash_seeds():
    # ezdxf writes the CLASS entries of the entity types in use by iterating a set of strings,
    # whose order follows the hash seed; fabkit sorts them
    path = str(TEMPLATES / "super_stable.toml")
    for flavour in ("lwpolyline", "line-arc"):
        digests = {_digest_here(path, flavour)}
        for seed in ("1", "2", "3"):
            env = dict(os.environ, PYTHONHASHSEED=seed)
            out = subprocess.run([sys.executable, "-c", _CODE.format(path=path, flavour=flavour)],
                                 env=env, capture_output=True, text=True, timeout=300, check=True)
            digests.add(out.stdout.strip())
        assert len(digests) == 1, flavour
