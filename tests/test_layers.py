"""The package reads as the pipeline: no module imports a package further down it."""

from __future__ import annotations

import ast
from pathlib import Path

import sensorgap

#: Pipeline order; a module may import its own layer and the layers before it.
LAYERS = [
    "earlystop",
    "errors",
    "locks",
    "atomic",
    "filesio",
    "registry",
    "plugins",
    "provenance",
    "runtime",
    "jit",
    "version",
    "apinames",
    "markdown",
    "config",
    "models",
    "coverage",
    "roads",
    "analysis",
    "scenarios",
    "search",
    "tradeoff",
    "export",
    "report",
    "stale",
    "steps",
    "jobs",
    "api",
    "cli",
    "entry",
]
#: Shared base modules count as one layer (they may import each other): those listed
#: before ``config``.
_BASE = set(LAYERS[: LAYERS.index("config")])
ROOT = Path(sensorgap.__file__).parent


def _layer(module: str) -> int:
    head = module.split(".")[0]
    if head in _BASE:
        return 0
    return LAYERS.index(head) - len(_BASE) + 1


def _imports(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            if node.module.startswith("sensorgap."):
                out.append(node.module.removeprefix("sensorgap."))
        elif isinstance(node, ast.Import):
            out += [
                a.name.removeprefix("sensorgap.")
                for a in node.names
                if a.name.startswith("sensorgap.")
            ]
    return out


def test_every_package_is_a_known_layer() -> None:
    names = {
        p.stem if p.is_file() else p.name
        for p in ROOT.iterdir()
        if (p.suffix == ".py" and p.stem != "__init__") or (p / "__init__.py").exists()
    }
    unknown = names - set(LAYERS) - {"__main__"}
    assert not unknown, f"add these to LAYERS in pipeline order: {sorted(unknown)}"


def test_no_import_goes_up_the_pipeline() -> None:
    bad = []
    for path in sorted(ROOT.rglob("*.py")):
        rel = path.relative_to(ROOT).with_suffix("")
        own = rel.parts[0]
        if own in ("__init__", "__main__"):
            continue
        for mod in _imports(path):
            if mod.split(".")[0] in LAYERS and _layer(mod) > _layer(own):
                bad.append(f"{rel}: imports sensorgap.{mod}")
    assert not bad, "\n".join(bad)


def test_nothing_imports_the_root_package() -> None:
    """The root package is the facade on top of the pipeline: no module below imports it
    (``from sensorgap import ...`` or ``import sensorgap``), so no hidden loop runs through
    it; the root itself imports only base modules eagerly (the facade lazily)."""
    bad = []
    for path in sorted(ROOT.rglob("*.py")):
        rel = path.relative_to(ROOT)
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.ImportFrom)
                and node.module == "sensorgap"
                and node.level == 0
                and rel.as_posix() != "__init__.py"
            ):
                bad.append(f"{rel}: from sensorgap import ...")
            elif isinstance(node, ast.Import) and any(a.name == "sensorgap" for a in node.names):
                bad.append(f"{rel}: import sensorgap")
    assert not bad, "\n".join(bad)
    root = ast.parse((ROOT / "__init__.py").read_text(encoding="utf-8"))
    eager = [n.module for n in root.body if isinstance(n, ast.ImportFrom) and n.module]
    assert all(_layer(m.removeprefix("sensorgap.")) == 0 for m in eager), eager
