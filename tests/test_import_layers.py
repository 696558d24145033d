"""The package's layers, held from its source: no import circle between files or folders, no
import that runs upward (``overdrive.LAYERS``), no function-level import of the project's own
modules but the listed ones, at most three modules at the top, every folder's ``__init__``
saying what it may and must not import. The checker is shown to fail on each kind of breach."""

from __future__ import annotations

import ast
import itertools
import re
import subprocess
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import NamedTuple

import pytest

import overdrive

SRC = Path(overdrive.__file__).resolve().parent

LAZY_IMPORTS: dict[tuple[str, str], tuple[str, str]] = {
    # (importer, imported): (what the import would load, why it waits); a key ending in "."
    # is a prefix. Each entry is checked: the import does load that package or those modules.
    ("overdrive.cli.", "overdrive.run."): ("overdrive.run", "the runners load when a command "
                                           "runs: `overdrive --help` and node start-up stay fast"),
    ("overdrive.cli.", "overdrive.scenario."): ("overdrive.scenario", "as above"),
    ("overdrive.cli.", "overdrive.observe."): ("overdrive.observe", "as above"),
    ("overdrive.cli.", "overdrive.vehicle."): ("overdrive.vehicle", "as above"),
    ("overdrive.observe.mcap_log", "overdrive.observe.mcap_writer"): (
        "zstandard", "only a run that writes run.mcap needs the compressor"),
}
"""Function-level imports allowed: each for a heavy dependency, never for a circle."""
MAX_TOP_MODULES = 3


class Import(NamedTuple):
    importer: str
    imported: str
    lazy: bool       # inside a function
    line: int


def module_name(path: Path, root: Path, package: str = "overdrive") -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join([package, *parts])


def imports_in(source: str, importer: str, known: Iterable[str]) -> list[Import]:
    """The project's imports in ``source``, each resolved to the longest known module."""
    known = set(known)

    def resolve(name: str) -> str | None:
        while name:
            if name in known:
                return name
            name = name.rpartition(".")[0]
        return None

    found: list[Import] = []

    def visit(node: ast.AST, lazy: bool) -> None:
        for child in ast.iter_child_nodes(node):
            inner = lazy or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
            names: list[str] = []
            if isinstance(child, ast.Import):
                names = [a.name for a in child.names]
            elif isinstance(child, ast.ImportFrom) and child.level:
                found.append(Import(importer, "<relative import>", lazy, child.lineno))
            elif isinstance(child, ast.ImportFrom) and child.module:
                names = [f"{child.module}.{a.name}" for a in child.names]
            if isinstance(child, ast.Call) and _dynamic_import(child):
                names = [child.args[0].value]
            for name in names:
                target = resolve(name)
                if target is not None and target != importer and name.startswith("overdrive"):
                    found.append(Import(importer, target, lazy, child.lineno))
            visit(child, inner)

    visit(ast.parse(source), False)
    return found


def _dynamic_import(call: ast.Call) -> bool:
    """``importlib.import_module("overdrive...")`` or ``__import__("overdrive...")``: an import."""
    f = call.func
    named = (isinstance(f, ast.Name) and f.id in ("__import__", "import_module")) or (
        isinstance(f, ast.Attribute) and f.attr == "import_module")
    return named and bool(call.args) and isinstance(call.args[0], ast.Constant) \
        and isinstance(call.args[0].value, str) and call.args[0].value.startswith("overdrive")


def layer_of(module: str, layers: tuple[tuple[str, ...], ...]) -> tuple[int, str] | None:
    """``(rank, group)``: rank 0 is the bottom; group is the folder or bottom module."""
    parts = module.split(".")
    if len(parts) == 1:
        return (-1, "")           # the package face: its constants, below everything
    for rank, names in enumerate(reversed(layers)):
        if parts[1] in names:
            return rank, parts[1]
    return None


def circles(edges: Iterable[tuple[str, str]]) -> list[list[str]]:
    """Strongly connected groups of more than one node (Tarjan, iterative)."""
    graph: dict[str, set[str]] = {}
    for a, b in edges:
        graph.setdefault(a, set()).add(b)
        graph.setdefault(b, set())
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    counter = itertools.count()
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = next(counter)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = next(counter)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                group = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    group.append(member)
                    if member == node:
                        break
                if len(group) > 1:
                    found.append(sorted(group))
    return found


def lazy_entry(imp: Import, lazy_allowed: Mapping[tuple[str, str], object]) -> tuple | None:
    """The allow-list key that covers ``imp`` (exact names, or prefixes ending in ".")."""
    def covers(key: str, name: str) -> bool:
        return name.startswith(key) if key.endswith(".") else name == key

    return next((key for key in lazy_allowed
                 if covers(key[0], imp.importer) and covers(key[1], imp.imported)), None)


def breaches(imports: list[Import], layers: tuple[tuple[str, ...], ...],
             lazy_allowed: Mapping[tuple[str, str], str]) -> list[str]:
    """Every rule the imports break, one line each (empty: the layering holds)."""
    out = []
    for imp in imports:
        if imp.imported == "<relative import>":
            out.append(f"{imp.importer}:{imp.line}: a relative import (write the full name: "
                       "the layers are checked by name)")
            continue
        a, b = layer_of(imp.importer, layers), layer_of(imp.imported, layers)
        if a is None or b is None:
            out.append(f"{imp.importer}:{imp.line} -> {imp.imported}: not in overdrive.LAYERS")
            continue
        if a[1] != b[1] and b[0] >= a[0]:
            how = "sideways" if b[0] == a[0] else "upward"
            out.append(f"{imp.importer}:{imp.line} -> {imp.imported}: {how} import")
        if imp.lazy and lazy_entry(imp, lazy_allowed) is None:
            out.append(f"{imp.importer}:{imp.line} -> {imp.imported}: function-level import "
                       "not in LAZY_IMPORTS")
    for group in circles((i.importer, i.imported) for i in imports):
        out.append(f"file circle: {' <-> '.join(group)}")
    folder_edges = set()
    for imp in imports:
        a, b = layer_of(imp.importer, layers), layer_of(imp.imported, layers)
        if a and b and a[1] != b[1]:
            folder_edges.add((a[1] or "overdrive", b[1] or "overdrive"))
    for group in circles(folder_edges):
        out.append(f"folder circle: {' <-> '.join(group)}")
    return out


def package_imports(src: Path = SRC) -> list[Import]:
    files = {module_name(p, src): p for p in sorted(src.rglob("*.py"))}
    found = []
    for name, path in files.items():
        found += imports_in(path.read_text(encoding="utf-8"), name, files)
    return found


# ------------------------------------------------------------------------------- the package

def test_the_package_keeps_its_layers() -> None:
    assert breaches(package_imports(), overdrive.LAYERS, LAZY_IMPORTS) == []


def test_every_listed_lazy_import_exists() -> None:
    """A stale entry would hide a new one behind its name."""
    used = {lazy_entry(i, LAZY_IMPORTS) for i in package_imports() if i.lazy}
    assert set(LAZY_IMPORTS) - used == set()


@pytest.mark.parametrize("key", sorted(LAZY_IMPORTS))
def test_every_lazy_import_is_heavy_and_the_importer_does_not_load_it(key: tuple[str, str]) -> None:
    """The reason holds: the imported module loads the named package (or is that package),
    and the importer alone does not."""
    heavy = LAZY_IMPORTS[key][0]
    importer = key[0].rstrip(".") if not key[0].endswith(".") else "overdrive.cli.main"
    imported = sorted({i.imported for i in package_imports()
                       if i.lazy and lazy_entry(i, {key: ""}) is not None})
    probe = ("import importlib, sys\n"
             f"importlib.import_module({importer!r})\n"
             f"before = any(m == {heavy!r} or m.startswith({heavy + '.'!r}) for m in sys.modules)\n"
             f"for name in {imported!r}: importlib.import_module(name)\n"
             f"after = any(m == {heavy!r} or m.startswith({heavy + '.'!r}) for m in sys.modules)\n"
             "print(before, after)\n")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                          check=True, timeout=120)
    assert done.stdout.split() == ["False", "True"], (key, done.stdout, done.stderr)


def test_at_most_three_modules_at_the_top() -> None:
    top = sorted(p.name for p in SRC.glob("*.py"))
    assert len(top) <= MAX_TOP_MODULES, top


def test_every_folder_is_a_layer_and_says_what_it_may_import() -> None:
    named = {name for layer in overdrive.LAYERS for name in layer}
    for folder in sorted(p for p in SRC.iterdir() if p.is_dir() and p.name != "__pycache__"):
        assert folder.name in named, f"{folder.name}/ is in no layer of overdrive.LAYERS"
        doc = ast.get_docstring(ast.parse((folder / "__init__.py").read_text(encoding="utf-8")))
        assert doc, f"{folder.name}/__init__.py has no docstring"
        words = " ".join(doc.split())
        assert "May import" in words and "Must not import" in words, folder.name
        number = next(len(overdrive.LAYERS) - rank for rank, layer in enumerate(overdrive.LAYERS)
                      if folder.name in layer)
        assert f"Layer {number}" in words, f"{folder.name}: its docstring names another layer"


# ------------------------------------------------------------------------ the checker fails

LAYERS = (("top",), ("mid_a", "mid_b"), ("low",))
KNOWN = ("overdrive.top.x", "overdrive.mid_a.y", "overdrive.mid_b.z", "overdrive.low.w",
         "overdrive.top.v")


def _check(sources: dict[str, str], lazy_allowed: Mapping[tuple[str, str], str] = {}) -> list[str]:
    imports = [i for name, text in sources.items() for i in imports_in(text, name, KNOWN)]
    return breaches(imports, LAYERS, lazy_allowed)


def test_checker_passes_a_clean_layering() -> None:
    assert _check({"overdrive.top.x": "from overdrive.mid_a.y import f\n",
                   "overdrive.mid_a.y": "import overdrive.low.w\n"}) == []


def test_checker_finds_an_upward_import() -> None:
    found = _check({"overdrive.low.w": "from overdrive.mid_a.y import f\n"})
    assert found == ["overdrive.low.w:1 -> overdrive.mid_a.y: upward import"]


def test_checker_finds_a_sideways_import_between_folders_of_one_layer() -> None:
    found = _check({"overdrive.mid_a.y": "from overdrive.mid_b.z import f\n"})
    assert found == ["overdrive.mid_a.y:1 -> overdrive.mid_b.z: sideways import"]


def test_checker_finds_a_file_circle_even_through_function_imports() -> None:
    found = _check({"overdrive.top.x": "from overdrive.top.v import f\n",
                    "overdrive.top.v": "def g():\n    from overdrive.top.x import h\n"},
                   {("overdrive.top.v", "overdrive.top.x"): "listed"})
    assert found == ["file circle: overdrive.top.v <-> overdrive.top.x"]


def test_checker_finds_an_unlisted_function_level_import() -> None:
    source = "def g():\n    from overdrive.low.w import f\n"
    found = _check({"overdrive.top.x": source})
    assert found == ["overdrive.top.x:2 -> overdrive.low.w: function-level import not in "
                     "LAZY_IMPORTS"]
    assert _check({"overdrive.top.x": source}, {("overdrive.top.x", "overdrive.low.w"): "ok"}) == []


@pytest.mark.parametrize("line", ["importlib.import_module('overdrive.top.x')",
                                  "__import__('overdrive.top.x')"])
def test_checker_counts_a_dynamic_import(line: str) -> None:
    found = _check({"overdrive.low.w": f"import importlib\n{line}\n"})
    assert found == ["overdrive.low.w:2 -> overdrive.top.x: upward import"]


def test_checker_refuses_a_relative_import() -> None:
    imports = imports_in("from ..top import x\n", "overdrive.low.w", KNOWN)
    assert breaches(imports, LAYERS, {}) == [
        "overdrive.low.w:1: a relative import (write the full name: the layers are checked by name)"]


def test_checker_allows_a_listed_prefix_of_lazy_imports() -> None:
    source = "def g():\n    from overdrive.low.w import f\n"
    assert _check({"overdrive.top.x": source}, {("overdrive.top.", "overdrive.low."): "ok"}) == []
    assert _check({"overdrive.top.x": source}, {("overdrive.mid_a.", "overdrive.low."): "ok"}) != []


def test_checker_finds_a_folder_circle() -> None:
    found = _check({"overdrive.low.w": "from overdrive.top.x import f\n",
                    "overdrive.top.x": "from overdrive.low.w import g\n"})
    assert "folder circle: low <-> top" in found


@pytest.mark.parametrize("name", ["overdrive.elsewhere.q"])
def test_checker_finds_a_module_outside_every_layer(name: str) -> None:
    imports = imports_in("from overdrive.low.w import f\n", name, KNOWN)
    assert breaches(imports, LAYERS, {}) == [
        f"{name}:1 -> overdrive.low.w: not in overdrive.LAYERS"]


# ------------------------------------------------------------------- clocks and sockets

SANS_IO = ("servers", "safety", "dynamics", "vehicle", "messages", "jaus", "scenario")
"""Logic and codecs: the time is passed in, bytes go in and out; no clock, no socket, no thread."""
NO_FILES = ("servers", "safety", "dynamics", "vehicle", "messages", "jaus")
"""...and, but for the scenario files the scenario layer reads, no file either."""
EDGE_MODULES = frozenset({"socket", "_socket", "select", "selectors", "threading", "_thread",
                          "time", "asyncio", "concurrent", "multiprocessing", "subprocess",
                          "signal"})
CLOCK_CALLS = ("now", "utcnow", "today")
"""``datetime`` is a type a codec may convert (a JAUS time stamp); reading it from the clock is not."""
FILE_MODULES = frozenset({"os", "pathlib", "io", "shutil", "tempfile", "importlib"})
SOCKET_OWNERS = ("runtime/udp.py", "runtime/ports.py")
"""Where sockets are made: UDP for every JAUS edge; TCP probes when picking listener ports."""


def _sources(groups: tuple[str, ...]) -> list[Path]:
    paths: list[Path] = []
    for group in groups:
        paths += [SRC / f"{group}.py"] if (SRC / f"{group}.py").exists() else \
            sorted((SRC / group).rglob("*.py"))
    return paths


def _imported_roots(tree: ast.AST) -> set[str]:
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module.split(".")[0])
    return names


def _calls(tree: ast.AST, name: str) -> list[int]:
    """Lines calling ``name`` (``open``, ``socket.socket``) or ``__import__``."""
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            f = node.func
            dotted = f.id if isinstance(f, ast.Name) else (
                f"{f.value.id}.{f.attr}" if isinstance(f, ast.Attribute)
                and isinstance(f.value, ast.Name) else "")
            if dotted in (name, "__import__"):
                found.append(node.lineno)
    return found


def test_logic_and_codecs_touch_no_clock_socket_or_thread() -> None:
    found = []
    for path in _sources(SANS_IO):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        if bad := _imported_roots(tree) & EDGE_MODULES:
            found.append(f"{path.relative_to(SRC)}: imports {', '.join(sorted(bad))}")
        found += [f"{path.relative_to(SRC)}:{node.lineno}: reads the clock ({node.func.attr})"
                  for node in ast.walk(tree) if isinstance(node, ast.Call)
                  and isinstance(node.func, ast.Attribute) and node.func.attr in CLOCK_CALLS]
    assert found == []


def test_logic_and_codecs_read_no_file() -> None:
    found = []
    for path in _sources(NO_FILES):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        if bad := _imported_roots(tree) & FILE_MODULES:
            found.append(f"{path.relative_to(SRC)}: imports {', '.join(sorted(bad))}")
        found += [f"{path.relative_to(SRC)}:{line}: opens a file" for line in _calls(tree, "open")]
    assert found == []


def test_sockets_are_made_in_the_runtime_edge_only() -> None:
    makers = []
    for path in sorted(SRC.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        lines = _calls(tree, "socket.socket")
        lines += [n.lineno for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)
                  and n.module == "socket" and any(a.name == "socket" for a in n.names)]
        if lines:
            makers.append(str(path.relative_to(SRC)))
    assert sorted(makers) == sorted(SOCKET_OWNERS)


def test_one_module_opens_udp_sockets() -> None:
    opening = sorted(str(p.relative_to(SRC)) for p in SRC.rglob("*.py")
                     if "SOCK_DGRAM" in p.read_text(encoding="utf-8"))
    assert opening == ["runtime/udp.py"]


def test_the_readme_layout_names_every_folder_and_module() -> None:
    """The README's layout block matches the tree: every folder and module is named there."""
    readme = (SRC.parents[1] / "README.md").read_text(encoding="utf-8")
    block = readme[readme.index("## Layout"):]
    block = block[:block.index("```", block.index("```") + 3)]
    missing = []
    for path in sorted(SRC.rglob("*.py")):
        rel = path.relative_to(SRC)
        if rel.name in ("__init__.py", "__main__.py"):
            continue
        if len(rel.parts) == 1:
            name = rel.name
        else:
            name = rel.stem
            if f"{rel.parts[0]}/" not in block:
                missing.append(f"{rel.parts[0]}/")
        if not re.search(rf"(?<![\w.]){re.escape(name)}(?![\w])", block):
            missing.append(str(rel))
    assert sorted(set(missing)) == []
