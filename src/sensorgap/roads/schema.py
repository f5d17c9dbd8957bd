"""OpenDRIVE 1.7 XSD validation with the schema files shipped by scenariogeneration.

scenariogeneration installs the ASAM XSDs in a ``schemas`` folder beside its package in
site-packages; ``opendrive_17_core.xsd`` includes the road, lane, junction, object, signal
and railroad parts.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Any

from sensorgap.roads.xmlsafe import DEFAULT_MAX_BYTES, parse_xml_file

CORE_XSD = "opendrive_17_core.xsd"


def opendrive_xsd_path() -> Path:
    """Path of the OpenDRIVE 1.7 core XSD; ``FileNotFoundError`` with a clear message if the
    installed scenariogeneration does not ship it."""
    try:
        import scenariogeneration
    except ImportError as exc:  # pragma: no cover - a declared dependency
        raise FileNotFoundError(
            "the OpenDRIVE 1.7 XSD ships with scenariogeneration, which is "
            "not installed (pip install scenariogeneration)"
        ) from exc
    folder = Path(scenariogeneration.__file__).resolve().parent.parent / "schemas"
    path = folder / CORE_XSD
    if not path.is_file():
        raise FileNotFoundError(
            f"OpenDRIVE 1.7 XSD not found: expected {path} (installed with "
            "scenariogeneration >= 0.14); reinstall scenariogeneration"
        )
    return path


@lru_cache(maxsize=1)
def _schema() -> Any:
    import xmlschema

    return xmlschema.XMLSchema(str(opendrive_xsd_path()))


def xsd_errors(path: str | Path, limit: int = 20, max_bytes: int = DEFAULT_MAX_BYTES) -> list[str]:
    """OpenDRIVE 1.7 XSD violations of ``path`` (at most ``limit``, one line each: element
    path and reason); an empty list means the file is valid. The file is parsed with the
    hardened parser first (``InputError`` for hostile, oversized or malformed XML)."""
    root = parse_xml_file(path, max_bytes)
    errors: list[str] = []
    for err in _schema().iter_errors(root):
        reason = (err.reason or str(err)).replace("\n", " ")
        errors.append(f"{err.path}: {reason}")
        if len(errors) >= limit:
            break
    return errors
