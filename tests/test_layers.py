"""The package's imports run downwards only: no cycles, no upward imports, no private names across modules.

The imports are read from the source with ``ast`` (module-level and function-level alike, since a
function-level import couples the modules just as much); nothing is imported. A name in a
``from x import y`` is resolved to the submodule ``x.y`` when that is a module, else to ``x``.
Known violations would be listed once, in :data:`KNOWN`, naming the file pair (it is empty); a
violation not listed fails, and so does a listed one that no longer occurs (so the list only shrinks).
"""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "warpshade"

# The layer order, lowest first; a unit (a top-level subpackage or loose module of warpshade, or
# "warpshade" for the package's own __init__, the public facade) may import units of its own layer
# or of lower layers only:
#   _version: the package version, imports nothing; _startup: the command's Ctrl-C guard, stdlib only;
#   _atomic: write-then-rename file replacement (every atomic write), stdlib only;
#   _cache: the per-user disk cache of derived arrays (hemiraster's far field and LUT), numpy and _atomic only;
#   scene: the scene description (lights, materials, objects) the pipeline consumes; it needs
#     only geometry;
#   radiance: lights · transfer · BRDF, above visibility;
#   parallel: shading frames on worker processes and Dask clusters (and the Warp start-up every
#     process does), below the pipeline that uses it;
#   preview: the ray-cast viewer, imports nothing of warpshade, used by the CLI;
#   script: the scripting API, beside the facade that re-exports it.
# usd and bench sit above pipeline/planner (the USD boundary reads scenes into and writes runs out
# of the pipeline's types; the bench drives the methods); the CLI and the facade are on top.
LAYERS = [
    {"sh", "geometry", "_version", "_startup", "_atomic", "_cache"},
    {"lighting", "sim", "scene"},
    {"visibility"},
    {"radiance", "parallel", "preview"},
    {"pipeline", "planner"},
    {"usd", "bench"},
    {"cli", "__main__", "warpshade", "script"},
]

# Imports forbidden although the layer order allows them: the USD boundary converts files to and
# from arrays and scene descriptions; choosing methods is the pipeline's decision, not the reader's.
FORBIDDEN = {("usd", "pipeline"), ("usd", "planner")}

# Known violations, each (importing module, imported module): why it is here. Empty: the house imports
# downwards only. An entry may be added only with its reason, and is removed when the import is fixed.
KNOWN: dict[tuple[str, str], str] = {}


def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


MODULES = _modules()


def _imports() -> list[tuple[str, str, str | None, int]]:
    """Every import inside the package: (importer, imported module, imported name or None, line)."""
    found = []
    for mod, path in MODULES.items():
        is_pkg = path.name == "__init__.py"
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                found += [(mod, a.name, None, node.lineno) for a in node.names if a.name.split(".")[0] == "warpshade"]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = mod.split(".") if is_pkg else mod.split(".")[:-1]
                    base = base[:len(base) - (node.level - 1)]
                    target = ".".join(base + ([node.module] if node.module else []))
                else:
                    target = node.module or ""
                if target.split(".")[0] != "warpshade":
                    continue
                for a in node.names:
                    sub = f"{target}.{a.name}"
                    found.append((mod, sub, None, node.lineno) if sub in MODULES else (mod, target, a.name, node.lineno))
    return found


IMPORTS = _imports()


def _unit(mod: str, depth: int = 1) -> str:
    parts = mod.split(".")
    return ".".join(parts[:depth + 1]) if len(parts) > depth else mod


def _layer(unit: str) -> int:
    name = unit.split(".")[-1]
    for i, layer in enumerate(LAYERS):
        if name in layer:
            return i
    raise AssertionError(f"warpshade unit {unit!r} is in no layer: add it to LAYERS in tests/test_layers.py")


def _cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one node (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return out


def _is_ancestor(pkg: str, mod: str) -> bool:
    return mod.startswith(pkg + ".")


def _module_edges() -> dict[str, set[str]]:
    """Module graph without the known edges and without the edges from a module to a package
    containing it (``from .. import METHODS`` reads the package's ``__init__``, which re-exports its
    modules: not a dependency between peers)."""
    edges = defaultdict(set)
    for mod, target, _, _ in IMPORTS:
        if target != mod and not _is_ancestor(target, mod) and (mod, target) not in KNOWN:
            edges[mod].add(target)
    return edges


def test_the_reader_sees_the_imports_it_must():
    # guards against a reader that finds nothing (and so passes everything)
    pairs = {(m, t) for m, t, _, _ in IMPORTS}
    assert ("warpshade.lighting.kernels", "warpshade.geometry.kernels") in pairs
    assert ("warpshade.bench.runner", "warpshade.bench.area") in pairs  # a function-level import
    assert ("warpshade.visibility.gears.kernels", "warpshade.geometry.kernels") in pairs  # relative, level 3
    assert len(MODULES) > 100 and len(IMPORTS) > 300


def test_every_unit_has_a_layer():
    for mod in MODULES:
        _layer(_unit(mod))


def test_no_cycles_between_modules():
    cycles = _cycles(_module_edges())
    assert not cycles, "import cycles between modules: " + "; ".join(" <-> ".join(c) for c in cycles)


def test_no_cycles_between_subpackages():
    for depth in (1, 2):
        edges = defaultdict(set)
        for mod, target, _, _ in IMPORTS:
            a, b = _unit(mod, depth), _unit(target, depth)
            if a != b and not _is_ancestor(b, a) and (mod, target) not in KNOWN:
                edges[a].add(b)
        cycles = _cycles(edges)
        assert not cycles, f"import cycles between packages (depth {depth}): " + \
            "; ".join(" <-> ".join(c) for c in cycles)


def _violations() -> dict[tuple[str, str], str]:
    bad = {}
    for mod, target, name, line in IMPORTS:
        a, b = _unit(mod), _unit(target)
        where = f"{MODULES[mod].relative_to(PACKAGE.parent)}:{line}"
        if _layer(a) < _layer(b):
            bad.setdefault((mod, target), f"{where}: {a} (layer {_layer(a)}) imports {target} (layer {_layer(b)})")
        if (a.split(".")[-1], b.split(".")[-1]) in FORBIDDEN:
            bad.setdefault((mod, target), f"{where}: {a} must not import {b}")
        if name is not None and name.startswith("_") and not name.startswith("__") and target != mod:
            bad.setdefault((mod, target), f"{where}: private name {target}.{name}")
    return bad


def test_imports_run_downwards_and_name_nothing_private():
    new = {k: v for k, v in _violations().items() if k not in KNOWN}
    assert not new, "imports against the layer order (tests/test_layers.py LAYERS):\n" + "\n".join(sorted(new.values()))


def test_known_exceptions_still_occur():
    found = set(_violations())
    full = defaultdict(set)  # the module graph with the known edges kept in
    for mod, target, _, _ in IMPORTS:
        if target != mod and not _is_ancestor(target, mod):
            full[mod].add(target)
    in_cycles = {(a, b) for comp in _cycles(full) for a in comp for b in full[a] if b in comp}
    stale = [k for k in KNOWN if k not in found and k not in in_cycles]
    assert not stale, f"fixed, remove from KNOWN in tests/test_layers.py: {stale}"
