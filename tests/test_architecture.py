"""The layering of the Rust core (docs/architecture.md), checked on its sources.

- No import cycle: between the top-level modules of ``src/``, nor between the sibling files of
  any module folder (``use super::x`` and ``use crate::a::x`` within folder ``a``).
- pyo3 and numpy only at the edge (``src/lib.rs`` and ``src/python/``), so the core builds and
  tests without Python.
- No source file over 800 lines, tests aside (a ``tests.rs`` file or a trailing
  ``#[cfg(test)]`` module).
"""

import re
from collections import defaultdict
from pathlib import Path

SRC = Path(__file__).resolve().parent.parent / "src"
MAX_LINES = 800
EDGE = {"lib", "python"}

USE = re.compile(r"^\s*(?:pub(?:\([\w:]+\))?\s+)?use\s+([^;]+);", re.M)


def _code(path):
    """The file's text before its test module (tests may use anything)."""
    text = path.read_text()
    match = re.search(r"^#\[cfg\(test\)\]", text, re.M)
    return text[: match.start()] if match else text


def _without_comments(code):
    return re.sub(r"//[^\n]*", "", code)


def _module(path):
    """Module path of a source file, e.g. ['contact', 'local_step', 'moves']."""
    parts = list(path.relative_to(SRC).with_suffix("").parts)
    if parts[-1] in ("mod", "lib"):
        parts = parts[:-1]
    return parts


def _paths(use_tree, prefix=()):
    """Expand a use tree (``a::{b, c::d}``) into its paths."""
    use_tree = use_tree.strip()
    brace = use_tree.find("{")
    if brace < 0:
        return [tuple(prefix) + tuple(s for s in use_tree.split("::") if s)]
    head = [s for s in use_tree[:brace].split("::") if s]
    inner = use_tree[brace + 1 : use_tree.rindex("}")]
    items, depth, start = [], 0, 0
    for i, ch in enumerate(inner):
        depth += ch == "{"
        depth -= ch == "}"
        if ch == "," and depth == 0:
            items.append(inner[start:i])
            start = i + 1
    items.append(inner[start:])
    out = []
    for item in items:
        if item.strip():
            out += _paths(item, tuple(prefix) + tuple(head))
    return out


def _sources():
    """The core's source files, test modules aside (`tests.rs`, `*_tests.rs`, `tests/`):
    tests may use any layer without making it a dependency of the library."""
    return [
        p
        for p in SRC.rglob("*.rs")
        if p.name != "tests.rs" and not p.name.endswith("_tests.rs") and "tests" not in p.parts
    ]


def _graphs():
    """Edges between top-level modules, and between siblings of each folder."""
    top = defaultdict(set)
    siblings = defaultdict(lambda: defaultdict(set))
    for path in _sources():
        module = _module(path)
        if not module:
            continue
        code = _without_comments(_code(path))
        used = []
        for match in USE.finditer(code):
            used += _paths(re.sub(r"\s+as\s+\w+", "", match.group(1)))
        used += [("crate", m) for m in re.findall(r"\bcrate::(\w+)", code)]
        for p in used:
            if not p:
                continue
            if p[0] == "crate" and len(p) > 1:
                absolute = list(p[1:])
            elif p[0] == "super":
                # `use super::x` from file a/b/c.rs (module a::b::c) names a::b::x; from
                # a/b/mod.rs (module a::b) it names a::x.
                base = module[:-1]
                rest = list(p[1:])
                while rest and rest[0] == "super":
                    base, rest = base[:-1], rest[1:]
                absolute = base + rest
            else:
                continue
            if absolute and absolute[0] != module[0]:
                top[module[0]].add(absolute[0])
            # siblings: the deepest common folder of the two modules
            depth = 0
            while depth < min(len(module), len(absolute)) and module[depth] == absolute[depth]:
                depth += 1
            if depth < len(module) and depth < len(absolute):
                folder = tuple(module[:depth])
                siblings[folder][module[depth]].add(absolute[depth])
    return top, siblings


def _cycle(graph):
    """One cycle of `graph` as a list of nodes, or None."""
    state = {}

    def visit(node, trail):
        state[node] = "open"
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == "open":
                return trail[trail.index(nxt) :] + [nxt] if nxt in trail else [node, nxt]
            if nxt not in state:
                found = visit(nxt, trail + [nxt])
                if found:
                    return found
        state[node] = "done"
        return None

    for node in sorted(graph):
        if node not in state:
            found = visit(node, [node])
            if found:
                return found
    return None


def test_the_parser_sees_the_core_layers():
    """The checks below are only as good as the graph: the solver uses the membranes."""
    top, siblings = _graphs()
    assert "membrane" in top["solve"] and "solve" in top["gpu"]
    assert "initial_guess" in siblings[("solve",)]["sissm"]
    assert "family" in siblings[("solve",)]["initial_guess"]
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) is not None


def test_no_import_cycle_between_top_level_modules():
    top, _ = _graphs()
    core = {m: {d for d in deps if d not in EDGE} for m, deps in top.items() if m not in EDGE}
    assert _cycle(core) is None, f"import cycle between modules: {' -> '.join(_cycle(core))}"


def test_no_import_cycle_inside_a_module_folder():
    _, siblings = _graphs()
    cycles = {
        "::".join(folder) or "crate": " -> ".join(_cycle(graph))
        for folder, graph in siblings.items()
        if _cycle(graph)
    }
    assert not cycles, f"import cycles inside module folders: {cycles}"


def test_pyo3_and_numpy_only_at_the_edge():
    for path in _sources():
        module = _module(path)
        if not module or module[0] in EDGE:
            continue
        code = _code(path)
        assert not re.search(r"\b(pyo3|numpy)::", code), f"{path} uses pyo3/numpy outside src/python"


def test_no_source_file_over_800_lines_outside_tests():
    long = {
        str(p.relative_to(SRC)): n
        for p in _sources()
        if (n := _code(p).count("\n")) > MAX_LINES
    }
    assert not long, f"split these by concept (lines before their tests): {long}"
