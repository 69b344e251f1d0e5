"""The Numba kernel cache is keyed on the package sources (Numba alone misses edits of callees)."""

import os
import shutil
import subprocess
import sys

import numba

import rockfrac
from rockfrac import _kernel_cache as kc


def test_cache_directory_is_the_source_hash_of_this_package():
    if os.environ.get("NUMBA_CACHE_DIR"):
        assert rockfrac.KERNEL_CACHE is None
        return
    # the hash of the sources as imported (they may be edited while the tests run)
    assert rockfrac.KERNEL_CACHE.parent == kc.cache_root()
    assert len(rockfrac.KERNEL_CACHE.name) == 16 and int(rockfrac.KERNEL_CACHE.name, 16) >= 0
    assert numba.config.CACHE_DIR == str(rockfrac.KERNEL_CACHE)
    from rockfrac.laws import cohesive

    assert str(cohesive.ep_update._cache._cache_path).startswith(str(rockfrac.KERNEL_CACHE))


def test_any_source_edit_changes_the_cache_directory(tmp_path):
    pkg = tmp_path / "pkg"
    shutil.copytree(kc.PACKAGE, pkg, ignore=shutil.ignore_patterns("__pycache__"))
    before = kc.source_hash(pkg)
    assert before == kc.source_hash(kc.PACKAGE)
    params = pkg / "laws" / "cohesive_params.py"  # no kernel in it, but kernels freeze its constants
    params.write_text(params.read_text() + "\n")
    assert kc.source_hash(pkg) != before


def test_old_cache_directories_are_pruned(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    root = kc.cache_root()
    for k in range(6):
        (root / f"old{k}").mkdir(parents=True)
        os.utime(root / f"old{k}", (k, k))
    saved = numba.config.CACHE_DIR
    try:
        target = kc.configure()
    finally:
        numba.config.CACHE_DIR = saved
    assert target == root / kc.source_hash()
    assert sorted(d.name for d in root.iterdir()) == sorted([target.name, "old5", "old4", "old3"])


def test_user_cache_directory_wins(tmp_path):
    code = "import rockfrac, numba; print(rockfrac.KERNEL_CACHE, numba.config.CACHE_DIR)"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["None", str(tmp_path)]
