"""sensorgap: sensor-coverage gaps of automated vehicles turned into test scenarios.

Pipeline (data flows one way): ``config`` -> ``models`` -> ``coverage`` -> ``roads`` ->
``analysis`` -> (search, export, report) with a thin ``cli`` on top.
"""

from sensorgap.runtime import configure_numba_cache as _configure_numba_cache

__version__ = "0.1.0"

_configure_numba_cache()  # a writable numba cache folder even when installed read-only


def __getattr__(name: str) -> object:
    """Lazy top-level access to ``sensorgap.CriticalScenarios`` (the scenariogeneration
    generator of a search run's critical scenarios) without importing the pipeline."""
    if name == "CriticalScenarios":
        from sensorgap.export.generator import CriticalScenarios

        return CriticalScenarios
    raise AttributeError(f"module 'sensorgap' has no attribute {name!r}")
