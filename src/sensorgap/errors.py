"""The error types that may leave sensorgap's public API.

``InputError`` is bad input (a config file, a CLI argument, an OpenDRIVE file): the CLI
prints its one-line message and exits with code 2. Anything else escaping is an internal
error (exit code 1).
"""

from __future__ import annotations

from pathlib import Path


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
        # every line break Python knows (\r, \u2028, ...), not only \n: one line
        return ": ".join(" ".join(p.splitlines()) for p in parts)

    def lines(self) -> list[str]:
        """Every error found: this one, then the others, one line each."""
        return [self.line(), *(e.line() for e in self.more)]
