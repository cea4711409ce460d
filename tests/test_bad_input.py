"""Bad input: every case raises ValueError naming the offending index and/or value; no Rust panic
(pyo3 PanicException derives from BaseException) may reach Python."""

import re
import warnings

import numpy as np
import pytest

import peridyn
from conftest import make_grid, membrane

NAN = float("nan")
INF = float("inf")


def expect_value_error(fn, *patterns):
    """Call fn; it must raise ValueError (a panic or any other exception fails the test) whose
    message matches every regex in ``patterns`` (case-insensitive)."""
    try:
        fn()
    except BaseException as e:  # noqa: BLE001 - on purpose: a PanicException must fail here
        assert isinstance(e, ValueError), f"expected ValueError, got {type(e).__name__}: {e}"
        msg = str(e)
        for p in patterns:
            assert re.search(p, msg, flags=re.IGNORECASE), f"{p!r} not in message {msg!r}"
        return msg
    pytest.fail("no exception raised")


def expect_clean_error(fn, types=(ValueError, TypeError, OverflowError)):
    """Some inputs may fairly be a TypeError (wrong Python type) or an OverflowError (negative
    value for an unsigned argument); never a panic."""
    try:
        fn()
    except BaseException as e:  # noqa: BLE001
        assert isinstance(e, types), f"expected {types}, got {type(e).__name__}: {e}"
        return
    pytest.fail("no exception raised")


def new(v, t, **kw):
    args = dict(thickness=1e-3, density=100.0, material=peridyn.StretchA3(s0=1e3))
    args.update(kw)
    return lambda: peridyn.Membrane(v, t, **args)


@pytest.fixture
def mesh():
    return make_grid(4, 4, 1.0, 1.0)  # 16 vertices, 18 triangles


# ------------------------------------------------------------------------------------------------
# arrays of the mesh


def test_vertex_array_shapes(mesh):
    v, t = mesh
    expect_value_error(new(v[:, :2], t), r"vert", r"16\D+2\b")
    expect_value_error(new(v.ravel(), t), r"vert", r"48")
    expect_value_error(new(np.zeros((16, 3, 1)), t), r"vert")
    expect_value_error(new(np.zeros((0, 3)), np.zeros((0, 3), int)), r"vert|triang|empty")


def test_triangle_array_shapes(mesh):
    v, t = mesh
    expect_value_error(new(v, np.c_[t, t[:, :1]]), r"triang", r"18\D+4\b")
    expect_value_error(new(v, t.ravel()), r"triang", r"54")
    expect_value_error(new(v, np.zeros((0, 3), int)), r"triang|empty")


@pytest.mark.parametrize("bad", [NAN, INF, -INF])
def test_non_finite_vertex_names_index(mesh, bad):
    v, t = mesh
    v = v.copy()
    v[7, 1] = bad
    expect_value_error(new(v, t), r"\b7\b", r"nan|inf|finite")


def test_triangle_index_out_of_range(mesh):
    v, t = mesh
    t = t.copy()
    t[5, 2] = 19
    expect_value_error(new(v, t), r"\b5\b", r"\b19\b")
    t = mesh[1].copy()
    t[11, 0] = 2**40
    expect_value_error(new(v, t), r"\b11\b", str(2**40))


def test_negative_triangle_index(mesh):
    v, t = mesh
    t = t.copy()
    t[4, 1] = -1
    expect_value_error(new(v, t), r"\b4\b", r"-1\b")


def test_degenerate_triangle_repeated_index(mesh):
    v, t = mesh
    t = t.copy()
    t[3] = [t[3, 0], t[3, 0], t[3, 2]]
    expect_value_error(new(v, t), r"\b3\b")


def test_degenerate_triangle_zero_area():
    # 0-1-2 collinear on the x axis; 3 above: triangles 0 and 1 are fine, triangle 2 is a sliver of
    # zero area along edge 0-2 (edges 0-1 and 1-2 each in two triangles: manifold).
    v = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [1, 1, 0]], float)
    t = np.array([[0, 1, 3], [1, 2, 3], [0, 2, 1]])
    expect_value_error(new(v, t), r"\b2\b", r"area|degenerate|collinear")


def test_duplicate_triangle(mesh):
    v, t = mesh
    t2 = np.vstack([t, t[[6]]])  # triangle 18 repeats triangle 6
    expect_value_error(new(v, t2), r"\b18\b|\b6\b", r"duplicate")
    t3 = np.vstack([t, t[[6]][:, [1, 2, 0]]])  # same triangle, rotated index order
    expect_value_error(new(v, t3), r"\b18\b|\b6\b", r"duplicate")


def test_non_manifold_edge():
    # edge (3, 4) shared by three triangles with apexes 0, 1, 2
    v = np.array([[0, 1, 0], [0, -1, 0], [0, 0, 1], [-1, 0, 0], [1, 0, 0]], float)
    t = np.array([[3, 4, 0], [4, 3, 1], [3, 4, 2]])
    expect_value_error(new(v, t), r"manifold|edge", r"\b3\b", r"\b4\b")


def test_unused_vertex(mesh):
    v, t = mesh
    v2 = np.vstack([v, [[5.0, 5.0, 0.0]]])  # vertex 16 is in no triangle
    expect_value_error(new(v2, t), r"\b16\b")


# ------------------------------------------------------------------------------------------------
# scalar parameters


@pytest.mark.parametrize("name,value", [
    ("thickness", 0.0), ("thickness", -1.5), ("thickness", NAN), ("thickness", INF),
    ("density", 0.0), ("density", -2.5), ("density", NAN),
    ("bending", -0.25), ("bending", NAN),
    ("hourglass", -0.75), ("hourglass", NAN),
])
def test_bad_membrane_parameter(mesh, name, value):
    v, t = mesh
    pat = r"nan" if np.isnan(value) else (r"inf" if np.isinf(value) else re.escape(repr(value))
                                           .replace(r"\.0", r"(\.0*)?"))
    expect_value_error(new(v, t, **{name: value}), name, pat)


def test_bad_neighbors(mesh):
    v, t = mesh
    expect_value_error(new(v, t, neighbors=0), r"neighbo", r"\b0\b")
    expect_clean_error(new(v, t, neighbors=-1))


@pytest.mark.parametrize("kw", [dict(s0=-1.0), dict(s0=NAN), dict(s0=INF)])
def test_bad_stretch_a3(kw):
    pat = r"nan" if np.isnan(kw["s0"]) else (r"inf" if np.isinf(kw["s0"]) else r"-1")
    expect_value_error(lambda: peridyn.StretchA3(**kw), r"s0", pat)


@pytest.mark.parametrize("kw,name", [(dict(s0=-1.0, s1=1.0), "s0"), (dict(s0=1.0, s1=-3.0), "s1"),
                                     (dict(s0=NAN, s1=1.0), "s0"), (dict(s0=1.0, s1=NAN), "s1")])
def test_bad_neohookean(kw, name):
    expect_value_error(lambda: peridyn.NeoHookean(**kw), name)


def test_bad_from_young():
    expect_value_error(lambda: peridyn.StretchA3.from_young(1e5, 0.3), r"nu|poisson", r"0\.3")
    expect_value_error(lambda: peridyn.StretchA3.from_young(-1e5), r"-100000|-1(\.0*)?e\+?0*5")
    expect_value_error(lambda: peridyn.NeoHookean.from_young(1e5, 0.5), r"0\.5")  # s1 infinite
    expect_value_error(lambda: peridyn.NeoHookean.from_young(1e5, -1.0), r"-1")  # s0 infinite
    expect_value_error(lambda: peridyn.NeoHookean.from_young(0.0, 0.3))
    expect_value_error(lambda: peridyn.NeoHookean.from_young(NAN, 0.3), r"nan")


def test_wrong_material_type(mesh):
    v, t = mesh
    expect_clean_error(new(v, t, material="steel"))


@pytest.mark.parametrize("kw,pat", [
    (dict(dt=0.0), r"dt"), (dict(dt=-1e-3), r"dt"), (dict(dt=NAN), r"dt"), (dict(dt=INF), r"dt"),
    (dict(dt=1e-3, tol=-1e-6), r"tol"), (dict(dt=1e-3, tol=NAN), r"tol"),
    (dict(dt=1e-3, max_iters=0), r"max_iters"),
    (dict(dt=1e-3, gravity=(0.0, NAN, 0.0)), r"gravity"),
    (dict(dt=1e-3, gravity=(0.0, 1.0)), r"gravity|length|\b3\b"),
    (dict(dt=1e-3, acceleration="chebyshev", method="descent", contact=peridyn.Contact()),
     r"chebyshev.*contact.*sissm"),
    # the Chebyshev settings by the keywords users pass (before: "chebyshev rho", "... delay")
    (dict(dt=1e-3, chebyshev_rho=1.5), r"^chebyshev_rho must be in \(0, 1\), got 1\.5$"),
    (dict(dt=1e-3, acceleration="chebyshev", chebyshev_rho=0.0), r"^chebyshev_rho must be in"),
    (dict(dt=1e-3, chebyshev_delay=0), r"^chebyshev_delay must be >= 1 iteration, got 0$"),
    (dict(dt=1e-3, acceleration="chebyshev", chebyshev_delay=0), r"^chebyshev_delay must be"),
])
def test_bad_solver_parameter(kw, pat):
    expect_value_error(lambda: peridyn.Solver(**kw), pat)


def test_bad_solver_misc():
    expect_clean_error(lambda: peridyn.Solver(dt=1e-3, max_iters=-1))
    expect_clean_error(lambda: peridyn.Solver(dt=1e-3, threads=0))
    s = peridyn.Solver(dt=1e-3)
    expect_value_error(lambda: setattr(s, "dt", 0.0), r"dt")
    expect_value_error(lambda: setattr(s, "dt", NAN), r"dt")
    assert s.dt == 1e-3  # unchanged by the failed sets
    expect_clean_error(lambda: s.add("cloth"))
    expect_clean_error(lambda: s.add_collider("sphere"))


# ------------------------------------------------------------------------------------------------
# pins and state setters


def test_bad_pins(mesh):
    v, t = mesh
    m = membrane(v, t)
    expect_value_error(lambda: m.pin([0, 99]), r"\b99\b")
    expect_value_error(lambda: m.pin([-2]), r"-2\b")
    expect_value_error(lambda: m.pin([0, 1], np.zeros((3, 3))), r"target|shape", r"\b3\b")
    expect_value_error(lambda: m.pin([0, 1], np.zeros((2, 2))), r"target|shape")
    expect_value_error(lambda: m.pin([0, 1], [[0, 0, 0], [0, NAN, 0]]), r"nan|finite", r"\b1\b")
    expect_value_error(lambda: m.unpin([42]), r"\b42\b")
    assert m.pinned.shape == (0,)  # failed calls pinned nothing
    m.pin([2, 5])
    expect_value_error(lambda: setattr(m, "pin_targets", np.zeros((3, 3))), r"\b3\b|\b2\b")
    bad = np.zeros((2, 3))
    bad[1, 2] = INF
    expect_value_error(lambda: setattr(m, "pin_targets", bad), r"inf|finite")
    np.testing.assert_array_equal(m.pin_targets, v[[2, 5]])  # unchanged


@pytest.mark.parametrize("attr", ["positions", "velocities"])
def test_bad_state_setters(mesh, attr):
    v, t = mesh
    m = membrane(v, t)
    before = getattr(m, attr)
    expect_value_error(lambda: setattr(m, attr, np.zeros((15, 3))), r"15|16")
    expect_value_error(lambda: setattr(m, attr, np.zeros((16, 2))), r"\b2\b|shape")
    bad = v.copy()
    bad[5, 0] = NAN
    expect_value_error(lambda: setattr(m, attr, bad), r"\b5\b", r"nan|finite")
    bad[5, 0] = 0.0
    bad[9, 2] = -INF
    expect_value_error(lambda: setattr(m, attr, bad), r"\b9\b", r"inf|finite")
    np.testing.assert_array_equal(getattr(m, attr), before)  # unchanged


def test_bad_material_queries():
    mat = peridyn.StretchA3(s0=1.0)
    expect_value_error(lambda: mat.stress(np.ones((4, 2))), r"3|shape")
    expect_value_error(lambda: mat.energy_density(np.ones(5)), r"3|shape")


# ------------------------------------------------------------------------------------------------
# colliders


def test_bad_colliders():
    expect_value_error(lambda: peridyn.Sphere(center=(0, 0, 0), radius=0.0), r"radius", r"\b0")
    expect_value_error(lambda: peridyn.Sphere(center=(0, 0, 0), radius=-0.5), r"radius", r"-0\.5")
    expect_value_error(lambda: peridyn.Sphere(center=(0, 0, 0), radius=NAN), r"radius", r"nan")
    expect_value_error(lambda: peridyn.Sphere(center=(0, NAN, 0), radius=1.0), r"center|nan")
    expect_value_error(lambda: peridyn.Sphere(center=(0, 0), radius=1.0), r"center|length|\b3\b")
    expect_value_error(lambda: peridyn.Plane(normal=(0, 0, 0)), r"normal")
    expect_value_error(lambda: peridyn.Plane(normal=(0, NAN, 1)), r"normal|nan")
    expect_value_error(lambda: peridyn.Plane(point=(INF, 0, 0)), r"point|inf")
    sp = peridyn.Sphere(center=(0, 0, 0), radius=1.0)
    expect_value_error(lambda: sp.signed_distance(np.zeros((4, 2))), r"shape|3")


def cube():
    """Closed unit cube: 8 vertices, 12 outward triangles."""
    v = np.array([[x, y, z] for z in (0.0, 1.0) for y in (0.0, 1.0) for x in (0.0, 1.0)])
    quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    t = np.array([tri for q in quads for tri in ([q[0], q[1], q[2]], [q[0], q[2], q[3]])])
    return v, t


def test_bad_mesh_colliders():
    v, t = cube()
    nan = v.copy()
    nan[3, 2] = NAN
    expect_value_error(lambda: peridyn.MeshCollider(nan, t), r"vertex 3", r"non-finite")
    bad = t.copy()
    bad[7, 1] = 8
    expect_value_error(lambda: peridyn.MeshCollider(v, bad), r"triangle 7", r"index 8")
    bad[7, 1] = -1
    expect_value_error(lambda: peridyn.MeshCollider(v, bad), r"triangle 7", r"-1")
    expect_value_error(lambda: peridyn.MeshCollider(v, t[:-1]), r"not closed", r"edge")
    flipped = t.copy()
    flipped[4] = flipped[4, ::-1]
    expect_value_error(lambda: peridyn.MeshCollider(v, flipped), r"same direction", r"triangles? \d")
    sliver = v.copy()
    sliver[1] = sliver[0] + 1e-14 * (sliver[1] - sliver[0])
    expect_value_error(lambda: peridyn.MeshCollider(sliver, t), r"triangle \d+", r"degenerate")
    for res in (0, 1, -4):
        expect_value_error(lambda: peridyn.MeshCollider(v, t, resolution=res), r"resolution", str(res))
    expect_value_error(lambda: peridyn.MeshCollider(v, t, margin=-0.1), r"margin", r"-0\.1")
    expect_value_error(lambda: peridyn.MeshCollider(v), r"triangles")
    expect_value_error(lambda: peridyn.MeshCollider(v[:, :2], t), r"vertices", r"shape")
    expect_value_error(lambda: peridyn.MeshCollider(v, t[:, :2]), r"triangles", r"shape")


def test_bad_collider_poses(mesh):
    s = peridyn.Solver(dt=1e-3)
    s.add_collider(peridyn.Plane())
    expect_value_error(lambda: s.set_collider_pose(1, translation=(0, 0, 1)), r"index 1", r"1 collider")
    expect_value_error(lambda: s.set_collider_pose(-1), r"index -1")
    expect_value_error(lambda: s.collider_pose(2), r"index 2")
    skew = [[1, 0.1, 0], [0, 1, 0], [0, 0, 1]]
    expect_value_error(lambda: s.set_collider_pose(0, rotation=skew), r"rotation", r"orthonormal")
    mirror = np.diag([1.0, 1.0, -1.0])
    expect_value_error(lambda: s.set_collider_pose(0, rotation=mirror), r"rotation", r"det")
    nan = np.eye(3)
    nan[2, 0] = NAN
    expect_value_error(lambda: s.set_collider_pose(0, rotation=nan), r"rotation\[2\]\[0\]")
    expect_value_error(lambda: s.set_collider_pose(0, rotation=np.eye(2)), r"rotation", r"shape|3")
    expect_value_error(lambda: s.set_collider_pose(0, translation=(0, INF, 0)), r"translation\[1\]")


# ------------------------------------------------------------------------------------------------
# divergence


def test_diverging_step_raises_and_keeps_state(mesh):
    """Velocities of 1e300 make the step non-finite: DivergenceError (a RuntimeError), and the
    positions, velocities, time and step count stay exactly those before the step; after resetting
    the velocities, the solver steps normally again."""
    assert issubclass(peridyn.DivergenceError, RuntimeError)
    v, t = mesh
    m = membrane(v, t, bending=1e-3, hourglass=0.5)
    m.pin([0])
    s = peridyn.Solver(dt=1e-2, tol=1e-6, max_iters=20)
    s.add(m)
    s.step()
    s.step()
    vel = np.random.default_rng(0).choice([-1.0, 1.0], size=v.shape) * 1e300
    m.velocities = vel
    y_before = m.positions
    time_before, steps_before = s.time, s.steps_taken
    try:
        s.step()
    except BaseException as e:  # noqa: BLE001
        assert isinstance(e, peridyn.DivergenceError), f"{type(e).__name__}: {e}"
    else:
        pytest.fail("no DivergenceError")
    assert np.array_equal(m.positions, y_before)
    assert np.array_equal(m.velocities, vel)
    assert s.time == time_before and s.steps_taken == steps_before
    m.velocities = np.zeros_like(vel)
    st = s.step()
    assert np.all(np.isfinite(m.positions)) and st.step == steps_before


def runaway(max_speed):
    """A stretched cloth stepped by the paper's preconditioner without the step length of
    eq. 31-33, three iterations a step at dt = 0.1 s: a scheme that blows up. Returns the
    solver, the body and, for each step taken, its largest coordinate (m); stops at the first
    DivergenceError (returned too, else None) or after 40 steps."""
    v, t = make_grid(4, 4, 1.0, 1.0)
    m = membrane(v, t, bending=1e-3, hourglass=0.5)
    m.pin([0])
    m.positions = v * [3.0, 3.0, 1.0] + 0.3 * np.random.default_rng(0).normal(size=v.shape)
    s = peridyn.Solver(dt=0.1, tol=0.0, max_iters=3, preconditioner="paper",
                       step_length=False, max_speed=max_speed)
    s.add(m)
    largest = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", peridyn.PrecisionWarning)
        for _ in range(40):
            try:
                s.step()
            except peridyn.DivergenceError as e:
                return s, m, largest, e
            largest.append(np.abs(m.positions).max())
    return s, m, largest, None


def test_a_runaway_step_with_finite_positions_raises_and_keeps_state():
    """A blow-up passes through finite but absurd positions before any coordinate overflows
    (unchecked: above 1e15 m by step 8, 1e55 m by step 15, non-finite at 16): the solver's
    `max_speed` (default 10 km/s) stops it at the first step that ends faster (measured: step
    3, a vertex at 1.6e4 m/s, the cloth within 32 m), the message naming the vertex, the speed
    and `max_speed`, and the bodies keep the state before that step."""
    _, _, unchecked, _ = runaway(float("inf"))
    assert max(unchecked) > 1e15 and np.isfinite(unchecked).all(), unchecked
    s, m, largest, error = runaway(1e4)
    assert error is not None, largest
    assert re.search(r"vertex \d+ of body 0 reached [\d.]+e\+?0*4 m/s", str(error)), error
    assert "max_speed" in str(error)
    assert len(largest) < 8 and np.abs(m.positions).max() == largest[-1] < 1e3, largest
    assert s.steps_taken == len(largest)


def test_max_speed_spares_pinned_points_and_the_speeds_asked_for(mesh):
    """A cloth thrown at 2e4 m/s: refused at the default `max_speed` (the state kept), stepped
    once it is raised (setter) to 3e4 m/s or inf; a pinned cloth whose targets jump 1 km in a
    step (1e5 m/s) moves as prescribed, not diverging."""
    v, t = mesh
    m = membrane(v, t)
    s = peridyn.Solver(dt=1e-2)
    s.add(m)
    m.velocities = np.tile([2e4, 0.0, 0.0], (len(v), 1))
    x = m.positions
    with pytest.raises(peridyn.DivergenceError, match="max_speed"):
        s.step()
    assert np.array_equal(m.positions, x) and s.steps_taken == 0
    for limit in (3e4, float("inf")):
        s.max_speed = limit
        assert s.max_speed == limit
        s.step()
    pinned = membrane(v, t)
    pinned.pin(np.arange(len(v)))
    s = peridyn.Solver(dt=1e-2)
    s.add(pinned)
    pinned.pin_targets = pinned.pin_targets + [1e3, 0.0, 0.0]
    s.step()
    assert np.allclose(pinned.positions, v + [1e3, 0.0, 0.0])


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("-inf")])
def test_a_bad_max_speed_is_a_value_error_naming_it(bad):
    expect_value_error(lambda: peridyn.Solver(dt=1e-2, max_speed=bad), r"max_speed")
    s = peridyn.Solver(dt=1e-2)
    expect_value_error(lambda: setattr(s, "max_speed", bad), r"max_speed")
    assert s.max_speed == 1e4


def test_a_move_of_one_rounding_at_a_tiny_step_is_not_too_fast():
    """In f32 at dt = 1e-12 s a cloth 1 m from the origin moves by round-off only (gravity's
    fall, 1e-23 m, is far below an ulp): measured 4.0e-8 m in a step, which divided by dt
    reads 4e4 m/s, above the default max_speed. Such a move is never "too fast": the cloth
    steps."""
    v, t = make_grid(4, 4, 1.0, 1.0)
    m = membrane(v + [1.0, 0.0, 0.0], t)
    s = peridyn.Solver(dt=1e-12, precision="f32")
    s.add(m)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", peridyn.PrecisionWarning)
        for _ in range(3):
            s.step()
    assert np.all(np.isfinite(m.positions))


def test_a_pinned_jump_whose_f32_velocity_overflows_is_a_divergence(mesh):
    """A pinned cloth in f32 whose targets jump 1e36 m in a step of 1 ms: the velocity it
    would store, 1e39 m/s, overflows f32 (the speed check is exempt for pinned points, not
    the finiteness check): DivergenceError, the state kept; before, the step went through and
    stored infinite velocities."""
    v, t = mesh
    m = membrane(v, t)
    m.pin(np.arange(len(v)))
    s = peridyn.Solver(dt=1e-3, precision="f32")
    s.add(m)
    m.pin_targets = m.pin_targets + [1e36, 0.0, 0.0]
    x = m.positions
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", peridyn.PrecisionWarning)
        with pytest.raises(peridyn.DivergenceError, match="non-finite"):
            s.step()
    assert np.array_equal(m.positions, x) and np.all(np.isfinite(m.velocities))


# ------------------------------------------------------------------------------------------------
# particle bodies (issue 38-40)

S = 0.01  # lattice spacing of the particle bodies below (m)


def lattice(n, origin=(0.0, 0.0, 0.0)):
    """Particles on a cubic lattice of spacing S: n = (nx, ny, nz) sites from `origin` (m)."""
    axes = [np.arange(k) * S for k in n]
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3) + np.asarray(origin)


def frictional_sand():
    """A 3 x 3 x 3 block of sand with contact friction between its grains, released half a
    spacing above a plane: its grains touch, so the solver carries their friction
    multipliers from step to step."""
    s = peridyn.Solver(dt=2e-3, max_iters=10, tol=0.0)
    s.add(peridyn.Particles(lattice((3, 3, 3), (0.0, 0.0, 0.005)), spacing=S, density=1600.0,
                            material=peridyn.Granular(friction_angle=30.0, contact_friction=0.5)))
    s.add_collider(peridyn.Plane(friction=0.3))
    return s


def cloth_on_cloth():
    """A free 5 x 5 cloth 2.8 mm above a pinned one, within the barrier's reach of the 2 mm
    contact thickness: the contact local step's warm start and rest gaps are solver state."""
    v, t = make_grid(5, 5, 0.1, 0.1)
    under, over = membrane(v, t), membrane(v + [0.0, 0.0, 0.0028], t)
    under.pin(np.arange(len(v)))
    s = peridyn.Solver(dt=2e-3, max_iters=20, contact=peridyn.Contact(thickness=0.002))
    s.add(under)
    s.add(over)
    return s


@pytest.mark.parametrize("scene", [frictional_sand, cloth_on_cloth])
def test_a_diverging_step_keeps_the_solver_state_and_the_next_step_is_the_one_it_replaces(scene):
    """A step that raises DivergenceError (forced by a max_speed of 1 nm/s) keeps the solver's
    internal state (the grains' friction multipliers, the contact warm start) as well as the
    bodies: the step after it, with max_speed restored, is bit for bit the step an
    undisturbed twin takes. Before, the failed step's grain multipliers (and warm start) were
    kept, and the next step differed."""
    s, twin = scene(), scene()
    for _ in range(4):
        s.step()
        twin.step()
    state = s.internal_state()
    assert state["grain_contact_multipliers"].size or state["contact_warm_start"].size
    fail_a_step_keeping_the_internal_state(s)
    s.step()
    twin.step()
    assert_same_run(s, twin)


def fail_a_step_keeping_the_internal_state(s):
    """Forces a DivergenceError (max_speed 1 nm/s), asserts ``internal_state`` is as it was
    before the failed step, and restores ``max_speed``."""
    state, speed = s.internal_state(), s.max_speed
    s.max_speed = 1e-9
    with pytest.raises(peridyn.DivergenceError):
        s.step()
    after = s.internal_state()
    for key, value in state.items():
        assert np.array_equal(after[key], value), key
    s.max_speed = speed


def two_frictional_sands():
    """:func:`frictional_sand` and a second such block a spacing beside it (x from 3 cm)."""
    s = frictional_sand()
    s.add(peridyn.Particles(lattice((3, 3, 3), (0.03, 0.0, 0.005)), spacing=S, density=1600.0,
                            material=peridyn.Granular(friction_angle=30.0, contact_friction=0.5)))
    return s


def assert_same_run(s, twin):
    """Every body's positions and velocities and the solvers' internal states bit for bit."""
    for body, other in zip(s.bodies, twin.bodies):
        assert np.array_equal(body.positions, other.positions)
        assert np.array_equal(body.velocities, other.velocities)
    state = s.internal_state()
    for key, value in twin.internal_state().items():
        assert np.array_equal(state[key], value), key


def test_a_diverging_step_after_positions_are_set_keeps_the_state_the_next_step_takes():
    """Two frictional sand blocks, the first's positions set (to themselves) between steps:
    the next step starts that body's grain friction from 0, and ``internal_state`` says so
    already (the second body's contacts alone). A step that then raises DivergenceError
    leaves it as it was, and the step after it drops the friction and takes the stiffness
    again: bit for bit an undisturbed twin's. Before, the failed step's start was taken after
    loading the bodies had dropped the friction and recorded the positions as seen, so
    ``internal_state`` changed across the failed step (and reported, before it, friction the
    step discards)."""
    s, twin = two_frictional_sands(), two_frictional_sands()
    for _ in range(4):
        s.step()
        twin.step()
    for solver in (s, twin):
        solver.bodies[0].positions = solver.bodies[0].positions
    pairs = s.internal_state()["grain_contact_pairs"]
    assert len(pairs) and np.all(pairs >= 27)
    fail_a_step_keeping_the_internal_state(s)
    s.step()
    twin.step()
    assert_same_run(s, twin)


def test_a_state_saved_after_positions_are_set_continues_bit_for_bit(tmp_path):
    """``save_state`` right after a body's positions are set, then ``load_state`` into a fresh
    twin: both next steps are bit for bit the same. Before, the file held the body's grain
    friction, which the saving solver's next step dropped and the twin's kept."""
    s, twin = two_frictional_sands(), two_frictional_sands()
    for _ in range(4):
        s.step()
    s.bodies[0].positions = s.bodies[0].positions
    peridyn.load_state(peridyn.save_state(tmp_path / "state.npz", s), twin)
    s.step()
    twin.step()
    assert_same_run(s, twin)


@pytest.mark.parametrize("kick", ["velocities", "gravity"])
def test_a_granular_step_predicted_beyond_any_distance_is_a_divergence(kick):
    """Sand whose step would move it 1e297 m (velocities of 1e300 m/s, or gravity of 1e300
    m/s^2 at dt = 2 ms): the grains' contact search would need an infinite radius. That is a
    DivergenceError naming the particle, the bodies kept as before the step; before, a
    ValueError about "the horizon delta" escaped, which named nothing the user set."""
    gravity = (0.0, 0.0, -1e300) if kick == "gravity" else (0.0, 0.0, -9.81)
    s = peridyn.Solver(dt=2e-3, max_iters=10, gravity=gravity, max_speed=float("inf"))
    sand = peridyn.Particles(lattice((3, 3, 3), (0.0, 0.0, 0.005)), spacing=S, density=1600.0,
                             material=peridyn.Granular(friction_angle=30.0))
    s.add(sand)
    s.add_collider(peridyn.Plane())
    if kick == "velocities":
        sand.velocities = np.full((27, 3), 1e300)
    x, v = sand.positions, sand.velocities
    cause = r"vertex \d+ of body 0 has a predicted move .* without a finite square"
    with pytest.raises(peridyn.DivergenceError, match=cause):
        s.step()
    assert np.array_equal(sand.positions, x) and np.array_equal(sand.velocities, v)
    assert s.steps_taken == 0


@pytest.mark.parametrize("material", [peridyn.Elastic.from_young(1e5, 0.25),
                                      peridyn.Granular(friction_angle=30.0),
                                      peridyn.ViscoelasticFluid()])
def test_particles_at_the_same_place_are_refused_naming_both(material):
    """Two particles at one position would be joined by a bond of length 0, without a
    direction: before, the body was built and its first step diverged at iteration 0. Now a
    ValueError names both; `set_material` to a solid where a liquid's particles met is refused
    the same way, changing nothing."""
    x = lattice((3, 3, 3))
    x[7] = x[3]
    expect_value_error(lambda: peridyn.Particles(x, spacing=S, density=1000.0, material=material),
                       r"particles 3 and 7", r"same position")
    liquid = peridyn.Particles(lattice((3, 3, 3)), spacing=S, density=1000.0,
                               material=peridyn.ViscoelasticFluid())
    liquid.positions = x
    expect_value_error(lambda: liquid.set_material(peridyn.Elastic.from_young(1e5, 0.25)),
                       r"particles 3 and 7")
    assert isinstance(liquid.material, peridyn.ViscoelasticFluid)


@pytest.mark.parametrize("kw, pattern", [
    (dict(density=1e-320), r"^density 0\.0+1 kg/m\^3 .* particle mass of 0 kg"),
    (dict(density=1e308, spacing=1e3), r"^density 10+ kg/m\^3 .* particle mass of inf kg"),
    (dict(spacing=1e-320), r"^spacing 0\.0+1 m gives the default horizon"),
    (dict(spacing=1e308), r"^spacing 10+ m gives the default horizon"),
    (dict(spacing=1.0, horizon=1e200), r"^horizon must be .* whose square is a finite, normal"),
])
def test_a_spacing_or_density_whose_mass_or_horizon_overflows_is_named(kw, pattern):
    """Finite, positive, yet unusable: a particle mass ``density * spacing^3`` that is not a
    normal number (its inverse overflows; before, the body was built and its first step
    diverged) or a default horizon (2.2 spacings) whose square is not one (before, the error
    named "the horizon delta", which the user did not set)."""
    args = dict(spacing=S, density=1000.0, material=peridyn.Elastic.from_young(1e5, 0.25))
    args.update(kw)
    expect_value_error(lambda: peridyn.Particles(lattice((3, 3, 3)), **args), pattern)


@pytest.mark.parametrize("ratio", [NAN, INF, -1.0])
def test_granular_stiffness_refuses_a_bad_density_ratio(ratio):
    """Before, NaN and -1 read a stiffness of 0 Pa."""
    expect_value_error(lambda: peridyn.Granular(friction_angle=30.0).stiffness(ratio),
                       r"density_ratio")


@pytest.mark.parametrize("name", ["density_iterations", "redistribution_iterations"])
@pytest.mark.parametrize("value", [2.5, NAN, "5"])
def test_fluid_iteration_counts_that_are_not_integers_are_named(name, value):
    """Before, a TypeError said "'float' object cannot be interpreted as an integer" without
    naming the argument."""
    expect_value_error(lambda: peridyn.ViscoelasticFluid(**{name: value}), name)


@pytest.mark.parametrize("kw, name", [(dict(shear_modulus=1e308), "shear_modulus"),
                                      (dict(shear_modulus=5e307, bulk_modulus=1e308),
                                       "bulk_modulus")])
def test_fluid_moduli_whose_youngs_modulus_overflows_are_named(kw, name):
    """Before, the shear modulus was taken and building the body failed on "E", which the
    user never set."""
    expect_value_error(lambda: peridyn.ViscoelasticFluid(**kw), name)


def test_a_fluid_bodys_repr_shows_its_material():
    """Before, it showed the placeholder ``Elastic(mu=1, lam=0)`` a Newtonian liquid carries
    inside."""
    fluid = peridyn.ViscoelasticFluid(viscosity=0.5)
    body = peridyn.Particles(lattice((3, 3, 3)), spacing=S, density=1000.0, material=fluid)
    assert repr(fluid) in repr(body) and "Elastic" not in repr(body)


def newton_cloth():
    """A 20 x 20 cloth (0.3 m) hanging from two corners, stepped by Newton (dt 1/60 s)."""
    v, t = make_grid(20, 20, 0.3, 0.3)
    cloth = membrane(v, t, s0=1e4, hourglass=0.5)
    cloth.pin([0, 19])
    s = peridyn.Solver(dt=1 / 60, method="newton", tol=1e-7, max_iters=50)
    s.add(cloth)
    return s


@pytest.mark.parametrize("failed", [0, 5])
def test_a_newton_step_after_a_diverging_one_is_the_one_it_replaces(failed):
    """Newton's preconditioner (its coarse factor and when to refactor it) goes back to where a
    step that raised DivergenceError found it: the steps after it are bit for bit those of an
    undisturbed twin. Before, the failed step's factorisation was kept: after a failed first
    step (the coarse level not built yet) the cloth ended 3.2e-10 m from its twin's three steps
    later, after a failed sixth (a step that refactors: its factor values put back) 5.2e-10 m;
    a failed step 1-4 or 6-13 left no trace even then (review ab)."""
    s, twin = newton_cloth(), newton_cloth()
    for _ in range(failed):
        s.step()
        twin.step()
    fail_a_step_keeping_the_internal_state(s)
    for _ in range(3):
        s.step()
        twin.step()
    assert_same_run(s, twin)


def sand_block():
    """A 3 x 3 x 3 block of sand with friction at its grains' contacts, 5 mm up."""
    return peridyn.Particles(lattice((3, 3, 3), (0.0, 0.0, 0.005)), spacing=S, density=1600.0,
                             material=peridyn.Granular(friction_angle=30.0, contact_friction=0.5))


@pytest.mark.parametrize("kind", ["membrane", "particles"])
def test_a_body_belongs_to_the_solver_it_was_last_added_to(kind):
    """Added twice to one solver, a body is a ValueError naming its index. Added to a second
    solver, it is handed over: the second steps it (a body settled by one solver goes on in
    another, as the repose tests' layers do), and the first refuses to step it, a ValueError
    naming it, the body unchanged, until it is added to it again (which takes it back, in
    its place, its positions counted as replaced: the grain friction its own steps left is
    dropped; the second then refuses it). Before (review ab), both stepped it in turn, each seeing
    positions set from outside (the sand's friction at its grains' contacts dropped at every
    step: 1.0e-5 m from a run by one solver after 8 steps each)."""
    if kind == "membrane":
        body, named = membrane(*make_grid(4, 4, 1.0, 1.0)), r"Membrane of 16 vertices"
    else:
        body, named = sand_block(), r"Particles of 27 particles"
    first, second = peridyn.Solver(dt=2e-3), peridyn.Solver(dt=2e-3)
    for solver in (first, second):
        solver.add_collider(peridyn.Plane())
    first.add(body)
    for _ in range(20):  # the sand lands: its grains touch (36 frictional pairs, measured)
        first.step()
    if kind == "particles":
        assert first.internal_state()["grain_contact_pairs"].shape[0] > 0
    expect_value_error(lambda: first.add(body), rf"^this {named} is already body 0 of this solver")
    second.add(body)
    second.step()
    kept = body.positions.copy()
    expect_value_error(first.step, rf"^body 0 \({named}\) was added to another Solver since: a "
                       r"body is stepped by the solver it was last added to")
    np.testing.assert_array_equal(body.positions, kept)
    assert first.bodies[0] is body and second.bodies[0] is body
    first.add(body)
    assert first.bodies == [body]
    if kind == "particles":  # taken back: the friction its first steps left is of other positions
        assert first.internal_state()["grain_contact_pairs"].shape == (0, 2)
    first.step()
    expect_value_error(second.step, r"^body 0 .* was added to another Solver since")


@pytest.mark.parametrize("spacing, side", [(1e30, "above"), (4.1 * S, "above"),
                                           (1e-9, "below"), (S / 4.1, "below")])
@pytest.mark.parametrize("material", [peridyn.Elastic.from_young(1e5, 0.25),
                                      peridyn.ViscoelasticFluid()])
def test_a_spacing_far_from_the_particles_own_is_refused_naming_both(spacing, side, material):
    """Sites 1 cm apart given a spacing more than 4 times larger or smaller than that: a
    ValueError giving the spacing and the particles' median distance to their nearest
    neighbours. Before, a spacing of 1e30 m was taken (every pair a bond, each particle
    1e96 times too heavy) and stepped, and 1e-9 m failed on a particle without a
    three-dimensional neighbourhood, which named neither cause."""
    expect_value_error(
        lambda: peridyn.Particles(lattice((3, 3, 3)), spacing=spacing, density=1000.0,
                                  material=material),
        rf"^spacing [0-9.e-]+ m is [0-9.e]+ times {side} the median distance between the "
        r"particles and their nearest neighbours, 1e-2 m \(at most 4 times either way\)")


@pytest.mark.parametrize("spacing", [3.9 * S, S / 3.9])
def test_a_spacing_within_four_times_the_particles_own_is_taken(spacing):
    """Within the band both ways the body is built (with a horizon reaching the neighbours)."""
    horizon = None if spacing > S else 2.2 * S
    body = peridyn.Particles(lattice((3, 3, 3)), spacing=spacing, density=1000.0,
                             material=peridyn.Elastic.from_young(1e5, 0.25), horizon=horizon)
    assert body.spacing == spacing
