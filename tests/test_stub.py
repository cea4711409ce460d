"""The type stub `_core.pyi` describes exactly what the compiled module exposes."""

import ast
from pathlib import Path

import peridyn._core as core

STUB = Path(core.__file__).with_name("_core.pyi")


def stub_classes():
    """Every class of the stub with its members, inherited members (from stub bases) included."""
    tree = ast.parse(STUB.read_text())
    own, bases = {}, {}
    for node in tree.body:
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
