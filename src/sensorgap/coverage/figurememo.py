"""Figures drawn once per process for the same inputs: a figure's PNG bytes kept by a
digest of everything its drawing reads, written again (byte for byte) when the same
figure is asked for.

A figure is a pure function of its inputs (same inputs -> byte-identical PNG, tested), so
a process that writes one figure twice (the catalog coverage maps of several runs of one
vehicle exported from a script, a comparison and a job drawing a vehicle's near field, the
test suite) draws it once. The digest covers every value the drawing reads (arrays by
dtype, shape and bytes, floats by their hex form, configs by all their fields): two
figures that differ in anything drawn never share a PNG; anything the digest cannot
describe draws the figure (no memo). Module constants of the drawing code are not part of
the digest: code that changes them (a test) calls ``clear_memo()``."""

from __future__ import annotations

import dataclasses
import hashlib
import io
from collections import OrderedDict
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from pydantic import BaseModel

from sensorgap.atomic import atomic_write_bytes
from sensorgap.models.system import System

if TYPE_CHECKING:
    from matplotlib.figure import Figure

#: Figures kept (PNG bytes; sensorgap's are 0.05-0.35 MB: at most ~20 MB), least recently
#: used dropped first.
FIGURE_MEMO = 64
_pngs: OrderedDict[str, bytes] = OrderedDict()


def clear_memo() -> None:
    """Forget every kept figure (the next one is drawn again)."""
    _pngs.clear()


def _feed(h: Any, p: object) -> None:
    """Add ``p`` to the digest ``h``, tagged by its type; TypeError for a value it cannot
    describe completely."""
    if p is None or isinstance(p, (bool, int, str)):
        h.update(f"{type(p).__name__}:{p!r};".encode("utf-8", "backslashreplace"))
    elif isinstance(p, float):
        h.update(f"float:{p.hex()};".encode())
    elif isinstance(p, np.ndarray):
        if p.dtype.hasobject:
            raise TypeError("an object array")
        a = np.ascontiguousarray(p)
        h.update(f"array:{a.dtype.str}:{a.shape};".encode())
        h.update(a.tobytes())
    elif isinstance(p, np.generic):
        _feed(h, p.item())
    elif isinstance(p, Path):
        h.update(f"path:{p!s};".encode("utf-8", "backslashreplace"))
    elif isinstance(p, BaseModel):
        h.update(f"model:{type(p).__module__}.{type(p).__qualname__}(".encode())
        _feed(h, p.model_dump(mode="python"))
        h.update(b")")
    elif dataclasses.is_dataclass(p) and not isinstance(p, type):
        h.update(f"dataclass:{type(p).__module__}.{type(p).__qualname__}(".encode())
        for f in dataclasses.fields(p):
            if not f.name.startswith("_"):  # a cache (Conditions._cache), not an input
                h.update(f"{f.name}=".encode())
                _feed(h, getattr(p, f.name))
        h.update(b")")
    elif isinstance(p, (tuple, list)):
        h.update(f"{type(p).__name__}[{len(p)}](".encode())
        for x in p:
            _feed(h, x)
        h.update(b")")
    elif isinstance(p, dict):
        h.update(f"dict[{len(p)}](".encode())
        for k, v in p.items():  # in order: another order only misses
            _feed(h, k)
            _feed(h, v)
        h.update(b")")
    else:
        raise TypeError(f"no digest for a {type(p).__name__}")


def digest(*parts: object) -> str | None:
    """A digest of ``parts`` (None when one of them cannot be described completely)."""
    h = hashlib.blake2b(digest_size=24)
    try:
        _feed(h, parts)
    except TypeError:
        return None
    return h.hexdigest()


def drawn_system(system: System) -> tuple[object, ...]:
    """What a figure reads of a vehicle: its name, body and each sensor's id, type and
    mount (pose, fields of view, ranges)."""
    return (
        system.name,
        system.config.vehicle,
        tuple((s.id, s.type_name, s.mount) for s in system.sensors),
    )


def png_bytes(fig: Figure, dpi: int) -> bytes:
    """``fig`` as PNG at ``dpi`` without a timestamp in its metadata; closes it."""
    from sensorgap.runtime import pristine_matplotlib

    pristine_matplotlib()
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    try:
        fig.savefig(buf, format="png", dpi=dpi, metadata={"Software": None})
    finally:
        plt.close(fig)
    return buf.getvalue()


def save_drawn(
    key: tuple[object, ...], draw: Callable[[], Figure], path: str | Path, dpi: int = 120
) -> Path:
    """Write the PNG of the figure ``draw()`` makes to ``path`` atomically (as
    ``coverage.plot.save_figure``): drawn once per process for the same ``key`` (the
    figure's kind and every input the drawing reads) and ``dpi``, else written again from
    the kept bytes."""
    k = digest(dpi, *key)
    if k is None:
        return atomic_write_bytes(path, png_bytes(draw(), dpi))
    png = _pngs.get(k)
    if png is None:
        png = _pngs[k] = png_bytes(draw(), dpi)
        while len(_pngs) > FIGURE_MEMO:
            _pngs.popitem(last=False)
    else:
        _pngs.move_to_end(k)
    return atomic_write_bytes(path, png)
