"""Third-party extensions through ONE entry-point group, ``sensorgap.plugins``.

Each entry point names a module or a callable. Loading it (once per process, in name
order) must register whatever it adds with the public decorators:
``sensorgap.scenarios.register_kind`` (family kinds; families themselves are TOML files,
passed by path to ``--families``), ``sensorgap.search.metrics.register_metric`` and
``sensorgap.search.strategies.register_strategy``. A callable is called with no arguments.

``pyproject.toml`` of a plugin::

    [project.entry-points."sensorgap.plugins"]
    myplugin = "myplugin.sensorgap:register"
"""

from __future__ import annotations

from importlib.metadata import entry_points

from sensorgap.errors import InputError

GROUP = "sensorgap.plugins"
_loaded = False


def load_plugins() -> list[str]:
    """Load every entry point of ``GROUP`` once; returns the names loaded this call."""
    global _loaded
    if _loaded:
        return []
    _loaded = True
    names = []
    for ep in sorted(entry_points(group=GROUP), key=lambda e: e.name):
        try:
            obj = ep.load()
            if callable(obj):
                obj()
        except (Exception, SystemExit) as exc:  # noqa: BLE001 - a broken plugin: one line
            # (a plugin calling sys.exit(0) ended the command with exit 0 and no output)
            raise InputError(
                f"plugin {ep.name}", ep.value, f"failed to load: {type(exc).__name__}: {exc}"
            ) from None
        names.append(ep.name)
    return names
