"""Where the shipped presets (``templates/``) live."""

from __future__ import annotations

import os
from pathlib import Path

from sensorgap.errors import InputError

#: What a templates folder holds (``SENSORGAP_TEMPLATES``): folders, then files.
TEMPLATE_FOLDERS = ("vehicles", "scenarios")
TEMPLATE_FILES = ("environments.toml", "targets.toml", "reactions.toml")


def _templates_problem(path: Path) -> str | None:
    """What keeps ``path`` from being a templates folder (None: it is one)."""
    everything = ", ".join([*(f"{d}/" for d in TEMPLATE_FOLDERS), *TEMPLATE_FILES])
    if not path.exists():
        return f"does not exist; it must name a folder of presets ({everything})"
    if not path.is_dir():
        return f"is not a folder; it must name a folder of presets ({everything})"
    lacks = [f"{d}/" for d in TEMPLATE_FOLDERS if not (path / d).is_dir()]
    lacks += [f for f in TEMPLATE_FILES if not (path / f).is_file()]
    if lacks:
        return f"holds no {', '.join(lacks)}; it must name a folder of presets"
    if not any((path / "vehicles").glob("*.toml")):
        return "holds no vehicle preset (vehicles/*.toml); it must name a folder of presets"
    return None


def templates_dir() -> Path:
    """The templates folder: ``$SENSORGAP_TEMPLATES``, the source checkout's ``templates/``,
    or the copy packed into the wheel (``sensorgap/_templates``). A set variable must name
    a folder holding ``TEMPLATE_FOLDERS`` and ``TEMPLATE_FILES`` (at least one vehicle
    preset), else ``InputError`` naming the variable: a missing or empty folder read as
    a folder without presets ("unknown preset 'system_b'; presets: ", nothing listed)."""
    env = os.environ.get("SENSORGAP_TEMPLATES")
    if env:
        path = Path(env)
        problem = _templates_problem(path)
        if problem is not None:
            # a path as it is (a long one keeps its end: errors.clip); quoted when spaces
            # at its ends would not show
            shown = env if env.strip() == env else repr(env)
            raise InputError(
                "SENSORGAP_TEMPLATES",
                "",
                f"{shown} {problem} like the shipped templates/, or not be set",
            )
        return path
    here = Path(__file__).resolve()
    checkout = here.parents[3] / "templates"
    if (checkout / "vehicles").is_dir():
        return checkout
    return here.parents[1] / "_templates"


#: Why a preset name's path is refused when something other than a file stands there.
NOT_A_PRESET_FILE = (
    "is not a regular file (a folder, a device or a broken link): a preset is a .toml file"
)


def preset_file(
    folder: Path, name: str, field: str, kind: tuple[str, str], names: list[str]
) -> Path:
    """The shipped preset ``name`` of one kind: ``folder/<name>.toml``. ``InputError``
    when something other than a regular file stands there (``NOT_A_PRESET_FILE``, naming
    the path) or nothing does (naming ``field`` and listing the ``names`` there are;
    ``kind``: the singular and plural word for them)."""
    path = folder / f"{name}.toml"
    if os.path.lexists(path) and not path.is_file():
        raise InputError(path, "", NOT_A_PRESET_FILE)
    if not path.is_file():
        raise InputError(
            field,
            "",
            f"unknown {kind[0]} {name!r}; {kind[1]}: {', '.join(names)} "
            "(or a path to a .toml file)",
        )
    return path


def vehicle_presets() -> list[str]:
    """Names of the shipped vehicle presets (file stems under ``templates/vehicles``)."""
    return sorted(p.stem for p in (templates_dir() / "vehicles").glob("*.toml") if p.is_file())


def roads_dir() -> Path:
    """The shipped OpenDRIVE roads: ``$SENSORGAP_ROADS``, the checkout's ``roads/`` or the
    copy packed into the wheel (``sensorgap/_roads``). A set variable must name a folder
    holding at least one ``.xodr`` file, else ``InputError`` naming the variable."""
    env = os.environ.get("SENSORGAP_ROADS")
    if env:
        path = Path(env)
        if not path.is_dir() or not any(p.is_file() for p in path.glob("*.xodr")):
            # checked like SENSORGAP_TEMPLATES (hostile round 25: a bad value showed only
            # where a road was opened, after minutes of work, naming a derived path)
            shown = env if env.strip() == env else repr(env)
            what = "is not a folder" if not path.is_dir() else "holds no .xodr road"
            raise InputError(
                "SENSORGAP_ROADS",
                "",
                f"{shown} {what}; it must name a folder of OpenDRIVE roads (.xodr) like the "
                "shipped roads/, or not be set",
            )
        return path
    here = Path(__file__).resolve()
    checkout = here.parents[3] / "roads"
    if checkout.is_dir():
        return checkout
    return here.parents[1] / "_roads"


def shipped_road(name: str) -> Path:
    """The shipped road ``name`` (``roads_dir()/<name>.xodr``), which must exist: else
    ``InputError`` naming ``SENSORGAP_ROADS`` when it is set (hostile round 26: a folder
    lacking the far field's road failed after the work, naming only a derived path)."""
    path = resolve_road(name)
    if not path.is_file():
        env = os.environ.get("SENSORGAP_ROADS")
        if env:
            raise InputError(
                "SENSORGAP_ROADS",
                "",
                f"{env} holds no {path.name} (a shipped road this command needs); name a "
                "folder holding the shipped roads, or do not set it",
            )
        known = sorted(p.stem for p in roads_dir().glob("*.xodr"))
        if known:  # a name that is none of them (hostile round 32: "a broken installation")
            raise InputError(
                "road",
                "",
                f"unknown road {name!r} (no {path.name} among the shipped roads: "
                f"{', '.join(known)}; or give a path to an OpenDRIVE .xodr file)",
            )
        raise InputError(path, "", "the shipped road is missing (a broken installation)")
    return path


def resolve_road(name_or_path: str | Path) -> Path:
    """A road name (``motorway_r500``) from the shipped roads, or a path to an .xodr file."""
    text = str(name_or_path)
    if text.endswith(".xodr") or "/" in text:
        return Path(text)
    return roads_dir() / f"{text}.xodr"
