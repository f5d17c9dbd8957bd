"""A named registry of classes: sensor types, scenario kinds, metrics, strategies.

Each extension point of sensorgap is one ``Registry``; third-party packages add to it from
an entry point (loaded on the first lookup through ``on_lookup``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Generic, TypeVar

T = TypeVar("T")
C = TypeVar("C")


class Registry(Generic[T]):
    """Classes by name.

    Args:
        what: what the entries are, for messages (e.g. ``"sensor type"``).
        key: the name an entry is registered under (e.g. ``lambda c: c.name``).
        on_lookup: called before every lookup (loads plug-ins once).
    """

    def __init__(
        self, what: str, key: Callable[[T], str], on_lookup: Callable[[], object] | None = None
    ) -> None:
        self.what = what
        self._key = key
        self._on_lookup = on_lookup
        self._items: dict[str, T] = {}

    def register(self, item: C) -> C:
        """Register ``item`` under its key (a class decorator). Registering the same item again
        is a no-op; another item under a taken name raises ``ValueError``."""
        name = self._key(item)  # type: ignore[arg-type]
        existing = self._items.get(name)
        if existing is not None and existing is not item:
            raise ValueError(
                f"{self.what} {name!r} is already registered by "
                f"{getattr(existing, '__module__', '?')}"
            )
        self._items[name] = item  # type: ignore[assignment]
        return item

    def unregister(self, name: str) -> None:
        """Remove an entry (for tests and plug-in reloads)."""
        self._items.pop(name, None)

    def _lookup(self) -> None:
        if self._on_lookup is not None:
            self._on_lookup()

    def get(self, name: str) -> T | None:
        """The entry registered as ``name``, or ``None``."""
        if name not in self._items:
            self._lookup()
        return self._items.get(name)

    def names(self, sort: bool = True) -> list[str]:
        """Registered names, sorted (or in registration order)."""
        self._lookup()
        return sorted(self._items) if sort else list(self._items)

    def snapshot(self) -> dict[str, T]:
        """A copy of the entries, by name."""
        self._lookup()
        return dict(self._items)
