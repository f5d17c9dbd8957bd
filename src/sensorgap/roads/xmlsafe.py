"""Hardened XML parsing for untrusted road files.

Every road file is untrusted input. ``parse_xml_file`` refuses, with an ``InputError`` and
before any memory is committed to the document:

* files larger than ``max_bytes`` (default 50 MB), checked on the file size before reading;
* anything that is not a regular file (FIFOs, devices, folders);
* DOCTYPE declarations that declare entities (billion laughs, external entities / XXE) or
  reference an external DTD (``SYSTEM`` / ``PUBLIC``); a bare ``<!DOCTYPE OpenDRIVE>`` is
  harmless and accepted;
* malformed XML (reported with its line number).

The parser never resolves entities, never loads a DTD, never touches the network and keeps
libxml2's default limits on depth and text size (``huge_tree=False``).
"""

from __future__ import annotations

import re
import stat
from pathlib import Path

from lxml import etree

from sensorgap.errors import InputError

#: Default largest accepted file, bytes (50 MB; the biggest real OpenDRIVE maps are ~30 MB).
DEFAULT_MAX_BYTES = 50 * 1024 * 1024

# ASCII-compatible encodings (UTF-8, Latin-1, ...) are screened on the raw bytes before the
# parser sees them; others (UTF-16, UTF-32) are caught after a non-expanding parse.
_ENTITY_DECL = re.compile(rb"<!\s*ENTITY", re.IGNORECASE)
_DOCTYPE_EXTERNAL = re.compile(rb"<!DOCTYPE[^>\[]*\b(SYSTEM|PUBLIC)\b", re.IGNORECASE)

_DOCTYPE_MSG = (
    "DOCTYPE with entity declarations or an external DTD is not allowed "
    "(OpenDRIVE needs neither; entities are never expanded)"
)


def _parser() -> etree.XMLParser:
    return etree.XMLParser(
        resolve_entities=False,
        no_network=True,
        load_dtd=False,
        dtd_validation=False,
        huge_tree=False,
        remove_comments=True,
        remove_pis=True,
        collect_ids=False,
    )


def read_limited(path: str | Path, max_bytes: int = DEFAULT_MAX_BYTES) -> bytes:
    """Read a regular file of at most ``max_bytes`` bytes; ``InputError`` otherwise.

    The size is checked on the file's metadata first, so an oversized file costs nothing;
    the read itself is bounded as well (a file growing meanwhile is still refused).
    """
    p = Path(path)
    if max_bytes <= 0:
        raise ValueError(f"max_bytes must be > 0, got {max_bytes}")
    try:
        st = p.stat()
    except FileNotFoundError:
        raise InputError(p, "", "file not found") from None
    except OSError as exc:
        raise InputError(p, "", f"cannot read file: {exc.strerror}") from None
    if not stat.S_ISREG(st.st_mode):
        raise InputError(p, "", "not a regular file")
    too_big = f"file is larger than the limit of {max_bytes} bytes"
    if st.st_size > max_bytes:
        raise InputError(p, "", f"{too_big} ({st.st_size} bytes)")
    try:
        with open(p, "rb") as fh:
            data = fh.read(max_bytes + 1)
    except OSError as exc:
        raise InputError(p, "", f"cannot read file: {exc.strerror}") from None
    if len(data) > max_bytes:
        raise InputError(p, "", too_big)
    return data


def parse_xml_bytes(data: bytes, source: str | Path) -> etree._Element:
    """Parse ``data`` (the content of ``source``) with the hardened parser.

    Returns the root element. Raises ``InputError`` for malformed XML, entity declarations,
    external DTDs and unresolved entity references.
    """
    if _ENTITY_DECL.search(data) or _DOCTYPE_EXTERNAL.search(data):
        raise InputError(source, "DOCTYPE", _DOCTYPE_MSG)
    try:
        root = etree.fromstring(data, _parser())
    except etree.XMLSyntaxError as exc:
        line = exc.lineno if exc.lineno else 1
        msg = (exc.msg or "unreadable XML").splitlines()[0]
        raise InputError(source, f"line {line}", f"malformed XML: {msg}") from None
    except (ValueError, etree.LxmlError) as exc:  # e.g. unknown encoding declarations
        raise InputError(source, "", f"malformed XML: {exc}") from None
    if root is None:
        raise InputError(source, "", "malformed XML: empty document")
    info = root.getroottree().docinfo
    if info.doctype:
        dtd = info.internalDTD
        has_entities = dtd is not None and any(True for _ in dtd.iterentities())
        if has_entities or info.system_url or info.public_id:
            raise InputError(source, "DOCTYPE", _DOCTYPE_MSG)
    ent = next(root.iter(etree.Entity), None)
    if ent is not None:
        raise InputError(
            source, f"line {ent.sourceline}", f"entity reference {ent.text} is not allowed"
        )
    return root


def parse_xml_file(path: str | Path, max_bytes: int = DEFAULT_MAX_BYTES) -> etree._Element:
    """Read and parse an untrusted XML file; returns its root element.

    Args:
        path: the file.
        max_bytes: largest accepted file size, bytes (default 50 MB).

    Raises:
        InputError: missing/unreadable file, too large, hostile DOCTYPE, malformed XML.
    """
    return parse_xml_bytes(read_limited(path, max_bytes), path)
