"""The type stubs of the stub package `_core/` describe exactly what the compiled module
exposes: `__init__.pyi` re-exports what the concept files (`_materials.pyi`, `_bodies.pyi`, ...)
declare, and `contact.pyi` is the `contact` submodule."""

import ast
import re
from pathlib import Path

import pytest

import peridyn._core as core

STUBS = Path(core.__file__).with_name("_core")
INIT = STUBS / "__init__.pyi"
SUBMODULES = {"contact"}


def concept_files():
    """The stub files whose names the module's top level re-exports (not the submodules)."""
    return [p for p in sorted(STUBS.glob("*.pyi")) if p.stem not in SUBMODULES]


def top_level_nodes():
    return [node for path in concept_files() for node in ast.parse(path.read_text()).body]


def stub_classes():
    """Every class of the stub with its members, inherited members (from stub bases) included."""
    own, bases = {}, {}
    for node in top_level_nodes():
        if isinstance(node, ast.ClassDef):
            own[node.name] = {
                item.name
                for item in node.body
                if isinstance(item, ast.FunctionDef) and not item.name.startswith("__")
            }
            bases[node.name] = [b.id for b in node.bases if isinstance(b, ast.Name)]

    def members(name):
        out = set(own[name])
        for base in bases[name]:
            if base in own:
                out |= members(base)
        return out

    return {name: members(name) for name in own}


def public(obj):
    return {n for n in dir(obj) if not n.startswith("_")}


def test_every_stub_class_and_member_exists_in_the_module():
    for name, members in stub_classes().items():
        assert hasattr(core, name), f"stub declares {name}, the module does not have it"
        missing = members - public(getattr(core, name))
        assert not missing, f"{name}: stub declares {sorted(missing)} the module lacks"


def test_every_public_class_and_member_of_the_module_is_in_the_stub():
    stub = stub_classes()
    for name in public(core):
        obj = getattr(core, name)
        if not isinstance(obj, type) or issubclass(obj, BaseException):
            continue
        assert name in stub, f"module class {name} is missing from the stub"
        undocumented = public(obj) - stub[name]
        assert not undocumented, f"{name}: {sorted(undocumented)} missing from the stub"


def stub_literals():
    """The stub's module-level ``Literal`` aliases: name -> the strings they allow."""
    out = {}
    for node in top_level_nodes():
        value = getattr(node, "value", None)
        if (isinstance(node, ast.Assign) and isinstance(value, ast.Subscript)
                and isinstance(value.value, ast.Name) and value.value.id == "Literal"):
            elements = value.slice.elts if isinstance(value.slice, ast.Tuple) else [value.slice]
            out[node.targets[0].id] = {e.value for e in elements}
    return out


#: Each option alias of the stub: the keyword that takes it and the class of that keyword.
OPTIONS = {
    "Method": ("method", lambda **kw: core.Solver(dt=1e-3, **kw)),
    "Preconditioner": ("preconditioner", lambda **kw: core.Solver(dt=1e-3, **kw)),
    "Acceleration": ("acceleration", lambda **kw: core.Solver(dt=1e-3, **kw)),
    "Backend": ("backend", lambda **kw: core.Solver(dt=1e-3, **kw)),
    "Precision": ("precision", lambda **kw: core.Solver(dt=1e-3, **kw)),
    "GlobalSolver": ("global_solver", lambda **kw: core.Solver(dt=1e-3, **kw)),
    "DescentStep": ("step", core.Contact),
    "ProximalMetric": ("proximal", core.Contact),
}


@pytest.mark.parametrize("name", sorted(OPTIONS))
def test_the_stub_literals_are_the_strings_the_core_accepts(name):
    """A bad string's ValueError offers exactly the stub's strings ("none" is a quiet synonym
    of None), and each of them is accepted and read back by the getter of the same name (the
    GPU backend needs an adapter: not tried)."""
    allowed = stub_literals()[name]
    keyword, make = OPTIONS[name]
    with pytest.raises(ValueError) as bad:
        make(**{keyword: "bogus"})
    offered = set(re.findall(r"'([^']*)'", str(bad.value).split(", got")[0]))
    assert offered == allowed - {"none"}, str(bad.value)
    for value in sorted(allowed - {"gpu"}):
        assert getattr(make(**{keyword: value}), keyword) == (None if value == "none" else value)


def test_every_option_alias_of_the_stub_is_tested():
    assert set(stub_literals()) == set(OPTIONS)


def test_the_stub_package_re_exports_every_name_its_concept_files_declare():
    """A type checker sees `peridyn._core.X` only through `__init__.pyi`: each class, function
    and alias of a concept file is re-exported there under its own name (`import X as X`)
    from the file that declares it, and each submodule stub as itself."""
    declared = {}
    for path in concept_files():
        if path == INIT:
            continue
        for node in ast.parse(path.read_text()).body:
            if isinstance(node, (ast.ClassDef, ast.FunctionDef)):
                declared[node.name] = path.stem
            elif isinstance(node, ast.Assign):
                declared.update((t.id, path.stem) for t in node.targets if isinstance(t, ast.Name))
    exported = {
        alias.name: node.module or alias.name
        for node in ast.parse(INIT.read_text()).body
        if isinstance(node, ast.ImportFrom)
        for alias in node.names
        if alias.asname == alias.name
    }
    wrong = {n: (f, exported.get(n)) for n, f in declared.items() if exported.get(n) != f}
    assert not wrong, f"name: (declared in, re-exported from): {wrong}"
    assert all(exported.get(name) == name for name in SUBMODULES), exported


@pytest.mark.parametrize("name", sorted(SUBMODULES))
def test_each_submodule_stub_declares_exactly_the_submodules_functions(name):
    tree = ast.parse((STUBS / f"{name}.pyi").read_text())
    declared = {node.name for node in tree.body if isinstance(node, ast.FunctionDef)}
    assert declared == public(getattr(core, name))
