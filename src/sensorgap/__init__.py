"""sensorgap: sensor-coverage gaps of automated vehicles turned into test scenarios.

Pipeline (data flows one way): ``config`` -> ``models`` -> ``coverage`` -> ``roads`` ->
``analysis`` -> (search, export, report) with a thin ``cli`` and this facade on top.

Scripting (docs/api.md)::

    import sensorgap
    cov = sensorgap.coverage_grid("system_b", "glare_front_right", "car")
    run = sensorgap.find_scenarios("system_b", "out/b", families=["cut_in_right"])

The facade's names (``sensorgap.api``) are imported on first use, so ``import sensorgap``
stays light.
"""

from sensorgap.earlystop import install as _install_early_stop

# the ``sensorgap`` command (console script, ``python -m sensorgap``): stop signals are one
# line from here on, before this package's own start below (hostile round nineteen)
_install_early_stop()

from sensorgap.apinames import API_NAMES as _API  # noqa: E402 - the facade's names
from sensorgap.runtime import configure_matplotlib_dir as _configure_matplotlib_dir  # noqa: E402
from sensorgap.runtime import configure_numba_cache as _configure_numba_cache  # noqa: E402
from sensorgap.version import __version__  # noqa: E402

_configure_numba_cache()  # a writable numba cache folder even when installed read-only
_configure_matplotlib_dir()  # and matplotlib's, without its warning when HOME is read-only


def __getattr__(name: str) -> object:
    """The facade (``sensorgap.api``) and ``sensorgap.CriticalScenarios`` (the
    scenariogeneration generator of a search run's critical scenarios), lazily."""
    if name in _API:
        from sensorgap import api

        return getattr(api, name)
    if name == "CriticalScenarios":
        from sensorgap.export.generator import CriticalScenarios

        return CriticalScenarios
    raise AttributeError(f"module 'sensorgap' has no attribute {name!r}")


__all__ = ["CriticalScenarios", "__version__", *_API]
