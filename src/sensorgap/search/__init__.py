"""Search for critical scenarios: where and when a target stays undetected while it
becomes dangerous. See ``docs/search.md``."""

from sensorgap.plugins import GROUP, load_plugins

__all__ = ["GROUP", "load_plugins"]
