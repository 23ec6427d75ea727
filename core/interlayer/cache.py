"""An on-disk cache of results that do not change between runs (same inputs, same code, same library
versions), in the user's cache folder: ``$INTERLAYER_CACHE_DIR``, else ``$XDG_CACHE_HOME/interlayer``,
else ``~/.cache/interlayer``; ``INTERLAYER_CACHE_DIR=off`` turns it off. Entries are JSON files named by
the SHA-256 of their key; writes are atomic, and a cache that cannot be read or written is skipped."""
from __future__ import annotations

import hashlib
import json
import os
import tempfile
from pathlib import Path


def folder(kind: str) -> Path | None:
    """The cache's sub-folder ``kind`` (not created), or None when caching is off."""
    root = os.environ.get("INTERLAYER_CACHE_DIR")
    if root is not None and root.strip().lower() in ("", "off", "0", "no", "false"):
        return None
    if not root:
        root = os.path.join(os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"),
                            "interlayer")
    return Path(root) / kind


def digest(*parts) -> str:
    """The key of an entry: its parts (bytes, or anything with a stable ``repr``) hashed together."""
    h = hashlib.sha256()
    for part in parts:
        data = part if isinstance(part, bytes) else repr(part).encode()
        h.update(len(data).to_bytes(8, "little"))
        h.update(data)
    return h.hexdigest()


def load(kind: str, key: str):
    """The stored value, or None (not stored, caching off, or unreadable)."""
    base = folder(kind)
    if base is None:
        return None
    try:
        return json.loads((base / key[:2] / f"{key}.json").read_text())
    except (OSError, ValueError):
        return None


def store(kind: str, key: str, value) -> None:
    base = folder(kind)
    if base is None:
        return
    try:
        (base / key[:2]).mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile("w", dir=base / key[:2], suffix=".tmp", delete=False) as f:
            json.dump(value, f)
        os.replace(f.name, base / key[:2] / f"{key}.json")
    except OSError:
        pass
