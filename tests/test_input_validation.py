"""The Python edge refuses, with a ValueError naming the culprit, every input it would otherwise
take with a loss (issue 43): complex, bool and string values where real numbers are meant,
integers that do not fit, time steps the precision cannot step with, grids that cannot be
allocated, and reports thin sheets, rounded rotations and overflowing helpers truthfully; a str or
bool keyword given another type is a TypeError naming the keyword."""

import ast
import re
import warnings
from pathlib import Path

import numpy as np
import pytest

import peridyn
from conftest import make_grid, membrane
from test_bad_input import cube, expect_value_error


@pytest.fixture
def mesh():
    return make_grid(4, 4, 1.0, 1.0)  # 16 vertices, 18 triangles


def material():
    return peridyn.StretchA3(s0=1e3)


def new_membrane(v, t, **kw):
    args = dict(thickness=1e-3, density=100.0, material=material())
    args.update(kw)
    return peridyn.Membrane(v, t, **args)


# ------------------------------------------------------------------------------------------------
# 1. silent loss of information: complex, bool, strings, integers that do not fit


def array_entry_points(v, t):
    """(argument name, call taking the bad array) for every entry point that takes real arrays."""
    m = membrane(v, t)
    m.pin([0, 1])
    s = peridyn.Solver(dt=1e-3)
    s.add_collider(peridyn.Plane())
    sphere = peridyn.Sphere(center=(0, 0, 0), radius=1.0)
    cv, ct = cube()
    return {
        "vertices": lambda bad: new_membrane(bad(v), t),
        "positions": lambda bad: setattr(m, "positions", bad(v)),
        "velocities": lambda bad: setattr(m, "velocities", bad(np.zeros_like(v))),
        "targets": lambda bad: m.pin([2, 3], bad(v[[2, 3]])),
        "pin_targets": lambda bad: setattr(m, "pin_targets", bad(v[[0, 1]])),
        "gravity": lambda bad: peridyn.Solver(dt=1e-3, gravity=bad(np.array([0.0, 0.0, -9.81]))),
        "center": lambda bad: peridyn.Sphere(center=bad(np.zeros(3)), radius=1.0),
        "velocity": lambda bad: peridyn.Plane(velocity=bad(np.zeros(3))),
        "translation": lambda bad: s.set_collider_pose(0, translation=bad(np.zeros(3))),
        "rotation": lambda bad: s.set_collider_pose(0, rotation=bad(np.eye(3))),
        "points": lambda bad: sphere.signed_distance(bad(v)),
        "MeshCollider vertices": lambda bad: peridyn.MeshCollider(bad(cv), ct),
        "stretches": lambda bad: material().stress(bad(np.ones((2, 3)))),
        "p": lambda bad: peridyn.contact.point_triangle_distance(*[bad(v[:2])] + [v[:2]] * 3),
    }


LOSSY = {
    "complex": (lambda a: np.asarray(a, dtype=float) + 0.5j, r"complex"),
    "bool": (lambda a: np.asarray(a) != 0, r"bool"),
    "digit strings": (lambda a: np.asarray(a, dtype=float).astype(str), r"str|<U"),
}


@pytest.mark.parametrize("kind", sorted(LOSSY))
@pytest.mark.parametrize("entry", sorted(array_entry_points(*make_grid(4, 4, 1.0, 1.0))))
def test_lossy_array_dtypes_are_refused(mesh, entry, kind):
    convert, pattern = LOSSY[kind]
    call = array_entry_points(*mesh)[entry]
    name = entry.split()[-1]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        expect_value_error(lambda: call(convert), re.escape(name), pattern)
    assert not caught, [str(w.message) for w in caught]  # refused before numpy converts


def scalar_entry_points(v, t):
    """(argument name, call taking the bad scalar) for real and integer scalar arguments."""
    s = peridyn.Solver(dt=1e-3)
    s.add_collider(peridyn.Plane())
    cv, ct = cube()
    return {
        "dt": lambda x: peridyn.Solver(dt=x),
        "dt setter": lambda x: setattr(s, "dt", x),
        "tol": lambda x: peridyn.Solver(dt=1e-3, tol=x),
        "thickness": lambda x: new_membrane(v, t, thickness=x),
        "density": lambda x: new_membrane(v, t, density=x),
        "s0": lambda x: peridyn.StretchA3(s0=x),
        "E": lambda x: peridyn.NeoHookean.from_young(x, 0.3),
        "radius": lambda x: peridyn.Sphere(center=(0, 0, 0), radius=x),
        "friction": lambda x: peridyn.Plane(friction=x),
        "margin": lambda x: peridyn.MeshCollider(cv, ct, margin=x),
        "Contact thickness": lambda x: peridyn.Contact(thickness=x),
        "replace eps": lambda x: peridyn.Contact().replace(eps=x),
        "reach": lambda x: peridyn.contact.near_triangle_pairs(v, t, x),
        "time": lambda x: s.set_clock(x, 0),
    }


SCALARS = {
    "complex": (np.complex128(1e-3 + 1e-3j), r"complex"),
    "python complex": (complex(1e-3, 0.0), r"complex"),
    "bool": (True, r"bool"),
    "digit string": ("0.001", r"str"),
}


@pytest.mark.parametrize("kind", sorted(SCALARS))
@pytest.mark.parametrize("entry", sorted(scalar_entry_points(*make_grid(4, 4, 1.0, 1.0))))
def test_lossy_scalars_are_refused(mesh, entry, kind):
    value, pattern = SCALARS[kind]
    call = scalar_entry_points(*mesh)[entry]
    name = entry.split()[-1].replace("setter", "dt")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        expect_value_error(lambda: call(value), rf"\b{re.escape(name)}\b", pattern)
    assert not caught, [str(w.message) for w in caught]


@pytest.mark.parametrize("value,shown", [
    (True, r"bool"),
    (2**64, str(2**64)),
    (2.0, r"float"),
    ("3", r"str"),
])
@pytest.mark.parametrize("entry", ["neighbors", "max_iters", "resolution", "collider index"])
def test_integer_arguments_refuse_what_is_not_an_integer(mesh, entry, value, shown):
    v, t = mesh
    s = peridyn.Solver(dt=1e-3)
    s.add_collider(peridyn.Plane())
    call = {
        "neighbors": lambda: new_membrane(v, t, neighbors=value),
        "max_iters": lambda: peridyn.Solver(dt=1e-3, max_iters=value),
        "resolution": lambda: peridyn.MeshCollider(*cube(), resolution=value),
        "collider index": lambda: s.collider_pose(value),
    }[entry]
    expect_value_error(call, re.escape(entry), shown)


@pytest.mark.parametrize("index", [2**32, 2**32 + 1, 2**40, -(2**32), 2**63 - 1])
@pytest.mark.parametrize("method", ["pin", "unpin"])
def test_vertex_index_beyond_32_bits_is_not_truncated(mesh, index, method):
    """unpin([2**32]) used to unpin vertex 0: the index was cut to 32 bits on its way in."""
    v, t = mesh
    m = membrane(v, t)
    m.pin([0, 1])
    expect_value_error(lambda: getattr(m, method)([5, index]), r"indices\[1\]", str(index))
    np.testing.assert_array_equal(m.pinned, [0, 1])  # nothing pinned or released


@pytest.mark.parametrize("bad,shown", [
    (np.array([3, 2**64 - 1], dtype=np.uint64), str(2**64 - 1)),
    ([3, 2**64], str(2**64)),
    ([3, -(2**70)], str(-(2**70))),
])
def test_index_that_does_not_fit_in_64_bits_names_its_value(mesh, bad, shown):
    v, t = mesh
    m = membrane(v, t)
    m.pin([0])
    expect_value_error(lambda: m.unpin(bad), r"indices", r"entry 1", shown)
    np.testing.assert_array_equal(m.pinned, [0])


@pytest.mark.parametrize("offset,precision", [(1e12, "f64"), (1e5, "f32")])
def test_far_mesh_warns_that_its_motion_is_below_resolution(mesh, offset, precision):
    """A mesh 1e12 m from the origin cannot fall by g dt^2 = 1e-5 m in f64 (resolution there
    1e-4 m): the solver says so when the body is added and when it steps."""
    v, t = mesh
    m = membrane(v + offset, t)
    s = peridyn.Solver(dt=1e-3, precision=precision)
    with pytest.warns(peridyn.PrecisionWarning, match=r"resolution.*precision '%s'" % precision):
        s.add(m)
    with pytest.warns(peridyn.PrecisionWarning, match=r"\|g\| dt\^2"):
        s.step()
    near = membrane(v, t)
    s2 = peridyn.Solver(dt=1e-3, precision=precision)
    with warnings.catch_warnings():
        warnings.simplefilter("error", peridyn.PrecisionWarning)
        s2.add(near)
        s2.step()


# ------------------------------------------------------------------------------------------------
# 2. non-finite results without an exception


@pytest.mark.parametrize("dt,precision", [
    (1e-39, "f32"), (1e-30, "f32"), (1e-20, "f32"), (1e20, "f32"), (1e-160, "f64"), (1e-310, "f64"),
])
def test_time_step_the_precision_cannot_represent_is_refused(dt, precision):
    expect_value_error(lambda: peridyn.Solver(dt=dt, precision=precision), r"\bdt\b",
                       re.escape(f"'{precision}'"), r"<= dt <=")
    s = peridyn.Solver(dt=1e-3, precision=precision)
    expect_value_error(lambda: setattr(s, "dt", dt), r"\bdt\b", re.escape(f"'{precision}'"))
    assert s.dt == 1e-3


def test_smallest_f32_time_step_steps_finitely(mesh):
    """The limit is where dt^2 stops being a normal f32: just above it a step stays finite."""
    v, t = mesh
    m = membrane(v, t)
    s = peridyn.Solver(dt=2e-19, precision="f32", max_iters=3)
    with pytest.warns(peridyn.PrecisionWarning):  # g dt^2 is far below the resolution at 1 m
        s.add(m)
        s.step()
    assert np.all(np.isfinite(m.velocities)) and np.all(np.isfinite(m.positions))


def test_step_with_non_finite_velocities_raises_and_keeps_state(mesh):
    """Every vertex pinned to a target 1e306 m away: the positions stay finite but the
    velocities (y - x) / dt overflow; the step raises and leaves the last good state."""
    v, t = mesh
    m = membrane(v, t)
    s = peridyn.Solver(dt=1e-3, max_iters=2)
    s.add(m)
    s.step()
    m.pin(np.arange(len(v)), v + np.array([1e306, 0.0, 0.0]))
    x0, v0, time0 = m.positions, m.velocities, s.time
    with pytest.raises(peridyn.DivergenceError, match=r"non-finite"):
        s.step()
    np.testing.assert_array_equal(m.positions, x0)
    np.testing.assert_array_equal(m.velocities, v0)
    assert s.time == time0 and s.steps_taken == 1


# ------------------------------------------------------------------------------------------------
# 3. no panic reaches the user


@pytest.mark.parametrize("kw,pattern", [
    (dict(margin=1e30), r"margin"),
    (dict(margin=1e300), r"margin"),
    (dict(margin=1e6), r"margin"),
    (dict(resolution=2**62), r"resolution"),
    (dict(resolution=2**40, margin=0.0), r"resolution"),
])
def test_mesh_collider_grid_too_large_is_a_value_error(kw, pattern):
    expect_value_error(lambda: peridyn.MeshCollider(*cube(), **kw), pattern, r"nodes")


def test_negative_step_count_is_a_value_error():
    s = peridyn.Solver(dt=1e-3)
    expect_value_error(lambda: s.set_clock(0.0, -1), r"steps_taken", r"-1")


# ------------------------------------------------------------------------------------------------
# 4. messages that say the true reason


def test_thin_sheet_is_refused_for_its_thickness_not_collinear_neighbours():
    v, t = peridyn.grid(5, 5, (0.2, 0.2))
    msg = expect_value_error(lambda: new_membrane(v, t, thickness=1e-8), r"thickness", r"1e-0?8\b",
                             r"too small")
    assert "collinear" not in msg
    new_membrane(v, t, thickness=1e-6)  # a thin but representable sheet is accepted


def rotation_about_z(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@pytest.mark.parametrize("rounded", [
    lambda r: r.astype(np.float32).astype(np.float64),
    lambda r: r.astype(np.float32),
    lambda r: np.round(r, 7),
])
def test_rotation_rounded_to_float32_is_accepted_and_orthonormalised(rounded):
    r = rounded(rotation_about_z(0.3))
    s = peridyn.Solver(dt=1e-3)
    s.add_collider(peridyn.Plane())
    s.set_collider_pose(0, rotation=r)
    box = peridyn.Box(center=(0, 0, 0), half_extents=(1, 1, 1), rotation=r)
    q = np.asarray(box.rotation)
    np.testing.assert_allclose(q.T @ q, np.eye(3), atol=1e-14)
    np.testing.assert_allclose(q, r, atol=1e-6)
    skew = rotation_about_z(0.3) + 1e-4  # beyond the tolerance: still refused
    expect_value_error(lambda: s.set_collider_pose(0, rotation=skew), r"rotation", r"orthonormal")


# ------------------------------------------------------------------------------------------------
# 5. overflowing physical values


@pytest.mark.parametrize("args,pattern", [
    ((1e300, 0.3, 1e3), r"not finite"),
    ((1e200, 0.3, 1e100), r"not finite"),
    ((1e-300, 0.3, 1e-10), r"underflow"),
])
def test_plate_bending_stiffness_refuses_results_that_overflow(args, pattern):
    expect_value_error(lambda: peridyn.plate_bending_stiffness(*args), r"plate_bending_stiffness",
                       r"\bD\b", pattern)


@pytest.mark.parametrize("name,args", [
    ("E", ("4e4", 0.0, 1e-3)), ("nu", (4e4, True, 1e-3)), ("thickness", (4e4, 0.0, 1e-3 + 0j)),
])
def test_plate_bending_stiffness_refuses_non_real_input(name, args):
    expect_value_error(lambda: peridyn.plate_bending_stiffness(*args), rf"\b{name}\b", r"real")


# ------------------------------------------------------------------------------------------------
# 4. str and bool keywords of another type: a TypeError whose own message names the keyword


STUBS = Path(peridyn._core.__file__).with_name("_core")


def option_aliases():
    """The names the stubs give option strings (``Method = Literal[...]`` and the like)."""
    tree = ast.parse((STUBS / "_options.pyi").read_text())
    return {node.targets[0].id for node in tree.body if isinstance(node, ast.Assign)
            and isinstance(node.value, ast.Subscript) and ast.unparse(node.value).startswith("Literal")}


def str_and_bool_keywords():
    """Every (class, keyword, wanted, how) of the stubs whose keyword takes a str (or an option
    string; ``wanted`` "str or None" where None is accepted) or a bool, ``how`` "argument" for
    a constructor's argument or "setter" for a property's."""
    aliases, found = option_aliases(), []
    for path in sorted(STUBS.glob("*.pyi")):
        for cls in ast.parse(path.read_text()).body:
            if not isinstance(cls, ast.ClassDef):
                continue
            for item in cls.body:
                if not isinstance(item, ast.FunctionDef):
                    continue
                setter = any("setter" in ast.unparse(d) for d in item.decorator_list)
                if item.name != "__init__" and not setter:
                    continue
                for arg in item.args.args[1:] + item.args.kwonlyargs:
                    text = ast.unparse(arg.annotation) if arg.annotation else ""
                    optional = text.startswith("Optional[")
                    inner = text[len("Optional["):-1] if optional else text
                    wanted = "bool" if inner == "bool" else \
                        "str" if inner == "str" or inner in aliases else None
                    if wanted:
                        found.append((cls.name, item.name if setter else arg.arg,
                                      wanted + (" or None" if optional else ""),
                                      "setter" if setter else "argument"))
    return found


def make_with(mesh):
    """A call per class making it, with the keywords given."""
    v, t = mesh
    return {
        "Solver": lambda **kw: peridyn.Solver(dt=1e-3, **kw),
        "Contact": lambda **kw: peridyn.Contact(**kw),
        "ViscoelasticFluid": lambda **kw: peridyn.ViscoelasticFluid(**kw),
        "DruckerPrager": lambda **kw: peridyn.DruckerPrager(friction_angle=30.0, cohesion=0.0, **kw),
        "Membrane": lambda **kw: new_membrane(v, t, **kw),
    }


def test_the_str_and_bool_keywords_are_read_from_the_stubs():
    """The parametrised test below covers every str and bool keyword the stubs declare; a class
    that gains one must be added to ``make_with``."""
    keywords = str_and_bool_keywords()
    assert {cls for cls, *_ in keywords} <= set(make_with(make_grid(2, 2, 1.0, 1.0)))
    for expected in [("Solver", "global_solver", "str", "argument"),
                     ("Solver", "precision", "str or None", "argument"),
                     ("Solver", "two_level", "bool", "argument"),
                     ("Contact", "proximal", "str", "argument"),
                     ("ViscoelasticFluid", "density_solver", "str", "argument"),
                     ("ViscoelasticFluid", "adhesion", "bool", "argument"),
                     ("DruckerPrager", "rebuild_neighbours", "bool", "argument"),
                     ("Membrane", "self_contact", "bool", "setter")]:
        assert expected in keywords
    assert len(keywords) == 17


@pytest.mark.parametrize("cls, keyword, wanted, how", str_and_bool_keywords())
def test_a_str_or_bool_keyword_of_another_type_is_a_type_error_naming_it(mesh, cls, keyword,
                                                                         wanted, how):
    """``Solver(global_solver=3)``, ``ViscoelasticFluid(adhesion=1)`` and the like: the
    TypeError's own message names the keyword, the type it takes and the value given. Before,
    it said "'int' object is not an instance of 'str'" and only pyo3's exception note named
    the keyword. A setter says the same and changes nothing."""
    make = make_with(mesh)[cls]
    bad = 1 if wanted == "bool" else 3
    expected = rf"^{keyword} must be a {re.escape(wanted)}\b.*, got int {bad}$"
    if how == "argument":
        with pytest.raises(TypeError, match=expected):
            make(**{keyword: bad})
    else:
        made = make()
        before = getattr(made, keyword)
        with pytest.raises(TypeError, match=expected):
            setattr(made, keyword, bad)
        assert getattr(made, keyword) == before
