"""The names of the scripting facade (``sensorgap.api.__all__``), in a module of their own:
the root package offers them lazily (``sensorgap.coverage_grid`` imports the facade on first
use) and must not import the facade itself to list them."""

API_NAMES: tuple[str, ...] = (
    "Occluder",
    "coverage_grid",
    "evaluate_points",
    "export_catalog",
    "find_scenarios",
    "load_vehicle",
    "scene",
    "write_report",
)
