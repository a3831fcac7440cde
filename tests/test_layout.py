"""The package's shape: sub-packages in data-path order, no import circles,
nothing reaching up (docs/CONTRIBUTING.md, "Package layout").

Every ``import`` and ``from ... import`` of ``host/motecal`` is read with
``ast`` -- module level and inside functions alike (a lazy import is still a
dependency) -- and resolved to the module it loads.  A module may import from
its own layer of ``LAYERS`` (one sub-package each, but for the basics and the
command line) or a lower one, never from a higher one; and no set of modules
may import each other in a circle.
"""
from __future__ import annotations

import ast
import re
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
PACKAGE = REPO / "host" / "motecal"

# Bottom to top.  Each entry: the sub-packages (or root modules) of one layer.
LAYERS = [
    ("motecal", "motecal.errors", "motecal.jsonable", "motecal.maths"),  # basics
    ("motecal.line",),          # the serial line: protocol, sample decoding, sources
    ("motecal.sessions",),      # session data, still detection, store, import
    ("motecal.capture",),       # logging: link tracking, logger loop, guided flows
    ("motecal.view",),          # the browser view of a session (live and stored)
    ("motecal.calib",),         # calibration engine
    ("motecal.firmware",),      # the mote's rules on the host (fixed point, its C)
    ("motecal.targets",),       # a calibration in other tools' forms (export-cal)
    ("motecal.upload",),        # a calibration to a mote
    ("motecal.sim",),           # simulator
    ("motecal.diagnose",),      # model discrepancy
    ("motecal.report",),        # the paper's tables and figures
    ("motecal.commands", "motecal.__main__"),   # the CLI and its screens
]


def module_names(root: Path) -> dict[str, Path]:
    """Dotted name -> file, for every module and package under ``root``."""
    out = {}
    for p in sorted(root.rglob("*.py")):
        parts = list(p.relative_to(root.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = p
    return out


def import_graph(root: Path) -> dict[str, set[str]]:
    """Module -> the package's modules it imports (anywhere in its code)."""
    mods = module_names(root)
    top = root.name
    graph: dict[str, set[str]] = {m: set() for m in mods}
    for mod, path in mods.items():
        pkg = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = pkg.split(".")[: len(pkg.split(".")) - node.level + 1]
                    src = ".".join(base + ([node.module] if node.module else []))
                else:
                    src = node.module or ""
                # ``from pkg import sub`` loads the module pkg.sub
                targets = [f"{src}.{a.name}" if f"{src}.{a.name}" in mods else src
                           for a in node.names]
            else:
                continue
            for t in targets:
                if t.split(".")[0] != top:
                    continue
                while t not in mods:        # import a.b.c of a name: the module holding it
                    t = t.rpartition(".")[0]
                if t != mod:
                    graph[mod].add(t)
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
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

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def unit_of(mod: str, layers=LAYERS) -> tuple[int, str] | None:
    """(layer rank, the sub-package or root module it belongs to)."""
    best = None
    for rank, names in enumerate(layers):
        for n in names:
            if (mod == n or mod.startswith(n + ".")) and (best is None or len(n) > len(best[1])):
                best = (rank, n)
    return best


def upward(graph: dict[str, set[str]], layers=LAYERS) -> list[tuple[str, str]]:
    """Imports of a module in a higher layer."""
    return [(a, b) for a, targets in sorted(graph.items()) for b in sorted(targets)
            if unit_of(b, layers)[0] > unit_of(a, layers)[0]]


# ---------------------------------------------------------------------------
def test_every_module_has_a_layer():
    missing = [m for m in module_names(PACKAGE) if unit_of(m) is None]
    assert not missing, f"modules outside every layer of LAYERS: {missing}"


def test_no_import_circles():
    found = cycles(import_graph(PACKAGE))
    assert not found, f"import circles: {found}"


def test_no_import_against_the_layer_order():
    bad = upward(import_graph(PACKAGE))
    assert not bad, "imports from a higher layer: " + \
        ", ".join(f"{a} -> {b}" for a, b in bad)


def test_the_graph_sees_real_imports():
    """The reader resolves relative, lazy and ``from pkg import module`` imports."""
    g = import_graph(PACKAGE)
    assert "motecal.line.protocol" in g["motecal.line.sources"]           # from . import protocol
    assert "motecal.sessions.store" in g["motecal.commands.args"]         # inside a function
    assert "motecal.diagnose.summary" in g["motecal.diagnose.plots"]      # lazy, in a function
    assert "motecal.calib" in g["motecal.report.build"]                   # a package's names


def _package(tmp_path: Path, files: dict[str, str]) -> Path:
    root = tmp_path / "pkg"
    for name, text in files.items():
        p = root / name
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)
    return root


def test_a_planted_circle_and_an_upward_import_are_found(tmp_path):
    root = _package(tmp_path, {
        "__init__.py": "",
        "low/__init__.py": "",
        "low/a.py": "from . import b\n",
        "low/b.py": "def f():\n    from .a import x\n",                # circle a <-> b
        "low/c.py": "from ..high.h import y\n",                         # reaches up
        "high/__init__.py": "",
        "high/h.py": "from ..low import a\nimport pkg.low.b\n",          # fine: downwards
    })
    layers = [("pkg",), ("pkg.low",), ("pkg.high",)]
    g = import_graph(root)
    assert cycles(g) == [["pkg.low.a", "pkg.low.b"]]
    assert upward(g, layers) == [("pkg.low.c", "pkg.high.h")]
    assert g["pkg.high.h"] == {"pkg.low.a", "pkg.low.b"}


def test_contributing_describes_the_layers_in_order():
    text = (REPO / "docs" / "CONTRIBUTING.md").read_text()
    assert "tests/test_layout.py" in text
    pos = [text.find(f"`{names[0]}`") for names in LAYERS[1:]]
    assert all(p >= 0 for p in pos), [n for n, p in zip(LAYERS[1:], pos) if p < 0]
    assert pos == sorted(pos), "docs/CONTRIBUTING.md lists the layers in another order"
    assert re.search(r"no import circles", text, re.I)


def test_readme_layout_follows_the_layers():
    """README's one-line data path names the sub-packages in LAYERS' order
    (the newcomer reads the same order in README and CONTRIBUTING)."""
    row = next(line for line in (REPO / "README.md").read_text().splitlines()
               if line.startswith("| `host/motecal/` |"))
    named = re.findall(r"`(\w+)/`", row)
    order = [name.split(".")[1] for layer in LAYERS for name in layer if name.count(".") == 1
             and (PACKAGE / name.split(".")[1]).is_dir()]
    assert [n for n in order if n in named] == [n for n in named if n in order], (named, order)
