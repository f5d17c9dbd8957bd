"""The error types that may leave sensorgap's public API.

``InputError`` is bad input (a config file, a CLI argument, an OpenDRIVE file): the CLI
prints its one-line message and exits with code 2. Anything else escaping is an internal
error (exit code 1).
"""

from __future__ import annotations

import re
import sys
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
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
# one character of an escaped text: an escape (repr's or ``escape_unprintable``'s) or a
# plain character
_CHAR = re.compile(r"\\(?:x[0-9a-fA-F]{2}|u[0-9a-fA-F]{4}|U[0-9a-fA-F]{8}|.)|.", re.DOTALL)


def escape_unprintable(text: str) -> str:
    """``text`` with every character ``str.isprintable`` refuses written as ``\\xNN``,
    ``\\uNNNN`` or ``\\UNNNNNNNN`` (as ``repr`` does): control characters (ESC, which
    lets a file name clear a terminal), bidirectional and other format characters (U+202E
    turns the rest of a line around), separators and undecodable bytes (surrogates)."""
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


#: What a written document (report.md, report.html) shows escaped: every character
#: ``str.isprintable`` refuses but the line breaks and tabs of its text and the no-break
#: spaces it puts between a number and its unit
_KEPT_IN_DOCUMENTS = frozenset("\n\t\u00a0\u202f")


def escape_controls(text: str) -> str:
    """``text`` for a written document: as ``escape_unprintable``, but line breaks, tabs
    and no-break spaces kept (hostile round 35: a run folder named ``q<ESC>[2Jz`` was
    written raw into report.md, whose ``cat`` then cleared the terminal)."""
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() or c in _KEPT_IN_DOCUMENTS else repr(c)[1:-1] for c in text)


def _chars(text: str) -> list[str]:
    """``text`` (escaped) split into the characters it stands for: an escape is one."""
    return _CHAR.findall(text)


def _head(chars: list[str], width: int) -> list[str]:
    """The first of ``chars`` that fit in ``width`` characters of text (an escape whole)."""
    used = 0
    for n, c in enumerate(chars):
        used += len(c)
        if used > width:
            return chars[:n]
    return chars


def cut_quoted(text: str) -> str:
    """``text`` (a quoted value) cut to ``MAX_QUOTED_CHARS`` characters, saying how many
    characters the value has (an escape such as ``\\u202e`` is one, the quotes none)."""
    if len(text) <= MAX_QUOTED_CHARS:
        return text
    chars = _chars(text[1:-1])
    head = "".join(_head(chars, MAX_QUOTED_CHARS - 21))
    return f"{text[0]}{head}... ({len(chars)} characters)"


def cut_name(text: str) -> str:
    """``text`` (a path or another name) with unprintable characters escaped
    (``escape_unprintable``), cut to about ``MAX_NAMED_CHARS`` characters: its start and
    its end (a file's name) kept, saying how many characters it has (an escape is one)."""
    text = escape_unprintable(text)
    if len(text) <= MAX_NAMED_CHARS:
        return text
    keep = (MAX_NAMED_CHARS - 30) // 2
    chars = _chars(text)
    head = "".join(_head(chars, keep))
    tail = "".join(_head(chars[::-1], keep)[::-1])
    return f"{head}...{tail} ({len(chars)} characters)"


def clip(text: str) -> str:
    """One error line's text made safe to print: every unprintable character escaped
    (``escape_unprintable``: no terminal control or bidirectional override reaches the
    terminal), each quoted value cut to ``MAX_QUOTED_CHARS`` (``cut_quoted``), then each
    run of more than ``MAX_NAMED_CHARS`` characters without a space (a path, an option's
    value) cut as ``cut_name`` does. The one place every error line passes: it keeps a
    100 kB option value and a file name's escape sequences out of an error line, whatever
    message quoted or named them."""
    text = _QUOTED.sub(lambda m: cut_quoted(m.group(0)), escape_unprintable(text))
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
        parts = [self.source]
        if self.field:
            parts.append(self.field)
        parts.append(self.message)
        # in the message, every line break Python knows (\r, \u2028, ...), not only \n:
        # a space (a library's text over several lines reads on); then every value quoted
        # or named cut short and escaped (``clip``, ``cut_name``): a line break in a
        # file's name or a field is written as ``\n`` (hostile round twenty: a path
        # ``a<newline>b`` was shown as ``a b``, another file's name)
        parts[-1] = " ".join(parts[-1].splitlines())
        return ": ".join([cut_name(parts[0]), *(clip(p) for p in parts[1:])])

    def lines(self) -> list[str]:
        """Every error found: this one, then the others, one line each."""
        return [self.line(), *(e.line() for e in self.more)]


#: Lines already printed in this process (each warning or note once per folder).
_SAID: set[str] = set()


#: Lines held while a command runs (``notes_after_success``), printed when it succeeds.
_HELD_NOTES: list[list[str]] = []


def say(text: str) -> None:
    """One line on stderr, once per process (made safe and short by ``errors.clip``);
    held until the command succeeds inside ``notes_after_success``."""
    if text not in _SAID:
        _SAID.add(text)
        if _HELD_NOTES:
            _HELD_NOTES[-1].append(text)
        else:
            print(clip(f"sensorgap: {text}"), file=sys.stderr)


@contextmanager
def notes_after_success() -> Iterator[None]:
    """Hold ``say``'s lines while the block runs (a CLI command) and print them when it
    ends without an exception; a failed command prints its one error line only (remark of
    session 26: "input changed since the run", then the refusal of another input, two
    lines). A later command in the process says them again."""
    _HELD_NOTES.append([])
    try:
        yield
    except BaseException:
        _SAID.difference_update(_HELD_NOTES.pop())
        raise
    for text in _HELD_NOTES.pop():
        print(clip(f"sensorgap: {text}"), file=sys.stderr)


def shell_quote(arg: str) -> str:
    """``arg`` quoted for a POSIX shell (``shlex.quote``), or, when it holds bytes that
    are not valid UTF-8 (a path read with ``surrogateescape``) or control characters, as
    bash's ``$'...'`` with every such byte as ``\\xNN``: a "Reproduce with" line that can
    be pasted (a non-UTF-8 folder name showed as ``\\udcff``, which no shell reads back;
    remark of session 25)."""
    import shlex

    if not any(0xDC80 <= ord(c) <= 0xDCFF or not c.isprintable() for c in arg):
        return shlex.quote(arg)
    out = []
    for b in arg.encode("utf-8", "surrogateescape"):
        c = chr(b)
        if 0x20 <= b < 0x7F and c not in "'\\":
            out.append(c)
        else:
            out.append(f"\\x{b:02x}")
    return "$'" + "".join(out) + "'"


def shell_join(args: Iterable[str]) -> str:
    """``args`` as one shell command line, each quoted by ``shell_quote``."""
    return " ".join(shell_quote(a) for a in args)
