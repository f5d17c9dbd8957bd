"""Where the shipped presets (``templates/``) live."""

from __future__ import annotations

import os
from pathlib import Path


def templates_dir() -> Path:
    """The templates folder: ``$SENSORGAP_TEMPLATES``, the source checkout's ``templates/``,
    or the copy packed into the wheel (``sensorgap/_templates``)."""
    env = os.environ.get("SENSORGAP_TEMPLATES")
    if env:
        return Path(env)
    here = Path(__file__).resolve()
    checkout = here.parents[3] / "templates"
    if (checkout / "vehicles").is_dir():
        return checkout
    return here.parents[1] / "_templates"


def vehicle_presets() -> list[str]:
    """Names of the shipped vehicle presets (file stems under ``templates/vehicles``)."""
    return sorted(p.stem for p in (templates_dir() / "vehicles").glob("*.toml"))


def roads_dir() -> Path:
    """The shipped OpenDRIVE roads: ``$SENSORGAP_ROADS``, the checkout's ``roads/`` or the
    copy packed into the wheel (``sensorgap/_roads``)."""
    env = os.environ.get("SENSORGAP_ROADS")
    if env:
        return Path(env)
    here = Path(__file__).resolve()
    checkout = here.parents[3] / "roads"
    if checkout.is_dir():
        return checkout
    return here.parents[1] / "_roads"


def resolve_road(name_or_path: str | Path) -> Path:
    """A road name (``motorway_r500``) from the shipped roads, or a path to an .xodr file."""
    text = str(name_or_path)
    if text.endswith(".xodr") or "/" in text:
        return Path(text)
    return roads_dir() / f"{text}.xodr"
