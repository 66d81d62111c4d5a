"""Keep numba's on-disk caches of compiled loops in step with the kernels they call.

numba invalidates a cached function when the source file of THAT function changes, not
when a jitted function it calls changes (numba documentation, "Cache invalidation").
flex_model's integrators and the planner's loops call flex_model's compiled kernels, so
an entry compiled against an older ``flex_model/kernels.py`` could be loaded silently.
:func:`guard` stores a fingerprint of the dependency sources beside each dispatcher's
cache and flushes the cache when it differs. Nothing here changes results; it only
decides whether to recompile.
"""
from __future__ import annotations

import hashlib
from pathlib import Path


def fingerprint(files) -> str:
    """SHA-256 of the concatenated contents of ``files``."""
    digest = hashlib.sha256()
    for f in files:
        digest.update(Path(f).read_bytes())
    return digest.hexdigest()


def guard(dispatchers, dependency_files) -> None:
    """Flush the on-disk cache of each numba dispatcher whose dependencies changed."""
    try:
        stamp_value = fingerprint(dependency_files)
    except OSError:
        return
    for d in dispatchers:
        cache = getattr(d, "_cache", None)
        path = getattr(cache, "cache_path", None)
        if path is None or not hasattr(cache, "flush"):
            continue
        stamp = Path(path) / f"{d.py_func.__module__}.{d.py_func.__qualname__}.deps"
        try:
            if not stamp.is_file() or stamp.read_text() != stamp_value:
                cache.flush()
                stamp.write_text(stamp_value)
        except OSError:
            pass  # read-only cache location: numba itself then caches nothing there
