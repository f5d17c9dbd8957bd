"""The error types that may leave sensorgap's public API.

``InputError`` is bad input (a config file, a CLI argument, an OpenDRIVE file): the CLI
prints its one-line message and exits with code 2. Anything else escaping is an internal
error (exit code 1).
"""

from __future__ import annotations

import re
from pathlib import Path

#: Longest value quoted in an error line, characters (a longer one is cut: its first
#: ``MAX_QUOTED_CHARS - 20`` characters and its length; docs/limits.md).
MAX_QUOTED_CHARS = 80
#: Longest unquoted name (a file, folder or option value) in an error line, characters: a
#: longer one keeps its first and last ``(MAX_NAMED_CHARS - 30) // 2`` characters.
MAX_NAMED_CHARS = 200

# a value quoted by repr(): '...' or "..." with backslash escapes, not an apostrophe
# inside a word ("the table's key")
_QUOTED = re.compile(r"""(?<![\w'"\\])('(?:[^'\\\n]|\\.)*'|"(?:[^"\\\n]|\\.)*")(?!\w)""")
_LONG_RUN = re.compile(rf"\S{{{MAX_NAMED_CHARS + 1},}}")


def cut_quoted(text: str) -> str:
    """``text`` (a quoted value) cut to ``MAX_QUOTED_CHARS`` characters, saying how long
    it was."""
    if len(text) <= MAX_QUOTED_CHARS:
        return text
    return f"{text[: MAX_QUOTED_CHARS - 20]}... ({len(text)} characters)"


def cut_name(text: str) -> str:
    """``text`` (a path or another name) cut to about ``MAX_NAMED_CHARS`` characters: its
    start and its end (a file's name) kept, saying how long it was."""
    if len(text) <= MAX_NAMED_CHARS:
        return text
    keep = (MAX_NAMED_CHARS - 30) // 2
    return f"{text[:keep]}...{text[-keep:]} ({len(text)} characters)"


def clip(text: str) -> str:
    """One error line's text with every user value short: each quoted value cut to
    ``MAX_QUOTED_CHARS`` (``cut_quoted``), then each run of more than ``MAX_NAMED_CHARS``
    characters without a space (a path, an option's value) cut as ``cut_name`` does. The
    one place that keeps a 100 kB option value out of an error line, whatever message
    quoted it."""
    text = _QUOTED.sub(lambda m: cut_quoted(m.group(0)), text)
    return _LONG_RUN.sub(lambda m: cut_name(m.group(0)), text)


class InputError(Exception):
    """Bad input, reported as one line: ``<source>: <field>: <what is wrong / allowed>``.

    Args:
        source: the file (or CLI option, e.g. ``--extent``) the bad value came from.
        field: dotted path of the offending field inside ``source`` ('' if none).
        message: what is wrong and what is allowed.
    """

    def __init__(
        self, source: str | Path, field: str, message: str, more: list[InputError] | None = None
    ) -> None:
        self.source = str(source)
        self.field = field
        self.message = message
        #: further errors found in the same input (each printed on its own line)
        self.more: list[InputError] = list(more or [])
        super().__init__(self.line())

    def __reduce__(self) -> tuple[type[InputError], tuple[str, str, str, list[InputError]]]:
        """Picklable (raised in a worker process, re-raised in the parent)."""
        return (type(self), (self.source, self.field, self.message, self.more))

    def line(self) -> str:
        """The single line of this error (the first, when there are several)."""
        parts = [cut_name(self.source)]
        if self.field:
            parts.append(self.field)
        parts.append(self.message)
        # every line break Python knows (\r, \u2028, ...), not only \n: one line; every
        # value quoted or named cut short (``clip``)
        return ": ".join(clip(" ".join(p.splitlines())) for p in parts)

    def lines(self) -> list[str]:
        """Every error found: this one, then the others, one line each."""
        return [self.line(), *(e.line() for e in self.more)]
