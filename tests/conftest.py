"""Shared helpers and small fixtures for the peridyn validation suite.

The meshes are built here in plain numpy (independently of ``peridyn.grid``, which has its own
test in test_api.py) so that the physics tests do not depend on the code they check.
"""

import re

import numpy as np
import pytest
import trimesh

import peridyn

G = 9.81


# ----------------------------------------------------------------------------------------------
# meshes


def make_grid(nx, ny, a=1.0, b=1.0):
    """Flat rectangle in z = 0: x in [0, a] (nx vertices), y in [0, b] (ny vertices).

    Vertex index j*nx + i; two triangles per cell, counter-clockwise seen from +z.
    """
    x = np.linspace(0.0, a, nx)
    y = np.linspace(0.0, b, ny)
    X, Y = np.meshgrid(x, y)  # X[j, i] = x[i]
    verts = np.column_stack([X.ravel(), Y.ravel(), np.zeros(nx * ny)])
    tris = []
    for j in range(ny - 1):
        for i in range(nx - 1):
            v0 = j * nx + i
            tris.append([v0, v0 + 1, v0 + nx + 1])
            tris.append([v0, v0 + nx + 1, v0 + nx])
    return verts, np.asarray(tris, dtype=np.int64)


def icosphere(subdiv=1, radius=1.0):
    """Closed triangulated sphere (outward-oriented), 12 * 4^k-ish vertices."""
    t = (1.0 + 5.0**0.5) / 2.0
    v = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0],
         [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
         [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11],
         [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8],
         [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
         [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    verts = [np.array(p, float) / np.linalg.norm(p) for p in v]
    for _ in range(subdiv):
        cache = {}

        def mid(i, j):
            key = (min(i, j), max(i, j))
            if key not in cache:
                p = verts[i] + verts[j]
                verts.append(p / np.linalg.norm(p))
                cache[key] = len(verts) - 1
            return cache[key]

        nf = []
        for a, b, c in f:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            nf += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        f = nf
    return radius * np.array(verts), np.array(f, dtype=np.int64)


def cylinder_patch(nx, ny, radius=0.8, angle=1.2, length=1.0):
    """A piece of a cylinder of the given radius (axis along y), an opening angle in rad."""
    v, t = make_grid(nx, ny, angle, length)
    phi = v[:, 0] - angle / 2
    out = np.column_stack([radius * np.sin(phi), v[:, 1], radius * np.cos(phi)])
    return out, t


def one_ring(n, tris):
    nb = [set() for _ in range(n)]
    for tri in tris:
        for a in tri:
            for b in tri:
                if a != b:
                    nb[a].add(int(b))
    return nb


def k_ring(n, tris, k):
    ring1 = one_ring(n, tris)
    out = []
    for i in range(n):
        seen = {i}
        frontier = {i}
        for _ in range(k):
            frontier = set().union(*(ring1[v] for v in frontier)) - seen
            seen |= frontier
        out.append(seen - {i})
    return out


def triangle_areas(verts, tris):
    e1 = verts[tris[:, 1]] - verts[tris[:, 0]]
    e2 = verts[tris[:, 2]] - verts[tris[:, 0]]
    return 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)


def random_rotation(rng):
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


# ----------------------------------------------------------------------------------------------
# material formulas (independent re-statement of the model, used as the oracle)


def a3_energy(l, s0):
    l = np.asarray(l, float)
    return s0 * np.sum(((l**4 - 1) / 4 + (l**-2 - 1) / 2) / 3, axis=-1)


def a3_stress(l, s0):
    l = np.asarray(l, float)
    return s0 * (l**3 - l**-3) / 3


def nh_energy(l, s0, s1):
    l = np.asarray(l, float)
    J = np.prod(l, axis=-1)
    return s0 * (np.sum(l**2, axis=-1) - 3 - np.log(J**2)) + s1 * (J - 1) ** 2


def nh_stress(l, s0, s1):
    l = np.asarray(l, float)
    J = np.prod(l, axis=-1)[..., None]
    return 2 * s0 * (l - 1 / l) + 2 * s1 * (J - 1) * J / l


# ----------------------------------------------------------------------------------------------
# construction helpers


def membrane(verts, tris, *, s0=1e4, material=None, thickness=1e-3, density=200.0,
             bending=0.0, hourglass=0.0, neighbors=1):
    if material is None:
        material = peridyn.StretchA3(s0=s0)
    return peridyn.Membrane(verts, tris, thickness=thickness, density=density,
                            material=material, bending=bending, hourglass=hourglass,
                            neighbors=neighbors)


def plate_scene(half, *, speed=0.0, slant=0.0, lift=0.0, contact=False, backend="cpu",
                precision="f64"):
    """A free 8 x 8 cloth (0.2 m, 1 mm thick) 5 cm above a 0.6 m box plate ``2 half`` thick (m),
    the cloth shot at ``speed`` (m/s) down and ``slant`` (rad) towards +x, and the plate moving
    up at ``lift`` (m/s); dt = 10 ms, so a step at 5 m/s or more moves the cloth, or the plate,
    past the plate's thickness. Returns the solver, the membrane and the plate."""
    v, t = make_grid(8, 8, 0.2, 0.2)
    v[:, :2] -= 0.1
    v[:, 2] = 0.05
    m = peridyn.Membrane(v, t, thickness=1e-3, density=300.0,
                         material=peridyn.StretchA3(s0=2e4), bending=1e-6)
    m.velocities = np.tile([speed * np.sin(slant), 0.0, -speed * np.cos(slant)], (len(v), 1))
    extra = {"contact": peridyn.Contact(thickness=1e-3)} if contact else {}
    s = peridyn.Solver(dt=1e-2, tol=1e-4, max_iters=100, backend=backend, precision=precision,
                       **extra)
    s.add(m)
    plate = peridyn.Box(center=(0.0, 0.0, 0.0), half_extents=(0.3, 0.3, half),
                        velocity=(0.0, 0.0, lift))
    s.add_collider(plate)
    return s, m, plate


def turned(angle, axis):
    """Rotation matrix by `angle` (rad) about the unit `axis` (Rodrigues)."""
    k = np.asarray(axis, float)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


#: The slope of `slope_scene` (rad): tan = 0.5, so Coulomb friction holds a cloth for mu > 0.5.
SLOPE = np.arctan(0.5)
#: The time step of `slope_scene` (s).
SLOPE_DT = 2e-3


def slope_scene(backend, precision, shape, mu):
    """A free 12 x 12 cloth (0.3 m) lying at rest on a slope of angle SLOPE with Coulomb
    coefficient `mu`: a `Plane`, the top face of a turned `Box`, the top line of a `Capsule`
    of radius 20 m whose axis runs downhill (the cloth's sides sit at most 0.6 mm above it),
    or the top face of a `MeshCollider` of the turned box (its field is exact there: linear).
    Returns the membrane, its solver, the downhill direction and the start positions."""
    turn = turned(SLOPE, (0.0, 1.0, 0.0))  # x -> downhill (cos, 0, -sin); z -> the normal
    normal, downhill = turn[:, 2], turn[:, 0]
    v, t = make_grid(12, 12, 0.3, 0.3)
    m = membrane(v @ turn.T, t, material=peridyn.StretchA3(s0=2e4), thickness=1e-3,
                 density=300.0, bending=1e-5, hourglass=0.1)
    surface = -0.5e-3 * normal  # the cloth's mid-surface sits half its thickness above it
    under_centre = surface + 0.15 * downhill + np.array([0.0, 0.15, 0.0])
    if shape == "plane":
        collider = peridyn.Plane(point=surface, normal=normal, friction=mu)
    elif shape == "box":
        collider = peridyn.Box(center=under_centre - 0.1 * normal, half_extents=(1.0, 1.0, 0.1),
                               rotation=turn, friction=mu)
    elif shape == "capsule":
        axis = under_centre - 20.0 * normal
        collider = peridyn.Capsule(a=axis - 0.5 * downhill, b=axis + 0.5 * downhill,
                                   radius=20.0, friction=mu)
    elif shape == "mesh":
        box = trimesh.creation.box(extents=(2.0, 2.0, 0.2))
        vertices = box.vertices @ turn.T + (under_centre - 0.1 * normal)
        collider = peridyn.MeshCollider(vertices, box.faces, friction=mu)
    else:
        raise ValueError(f"unknown shape {shape!r}")
    # friction needs the step solved tightly: at tol = 1e-6 the iteration stops while the
    # tangential reaction is still short of the Coulomb bound (the cloth slides 5 % too far)
    sol = peridyn.Solver(backend=backend, precision=precision, dt=SLOPE_DT, tol=1e-8,
                         max_iters=60)
    sol.add(m)
    sol.add_collider(collider)
    return m, sol, downhill, v @ turn.T


def coulomb_slide(mu, steps):
    """How far (m) a block at rest on `slope_scene`'s slope slides in `steps` implicit Euler
    steps of SLOPE_DT with Coulomb coefficient `mu`: 0 where friction holds it (mu >= tan),
    else s_n = a h^2 n (n + 1) / 2 with a = g (sin - mu cos)."""
    a = G * (np.sin(SLOPE) - mu * np.cos(SLOPE))
    return max(a, 0.0) * SLOPE_DT**2 * steps * (steps + 1) / 2


def find_numbers(text):
    return [float(x) for x in re.findall(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?", text)]


def has_number(text, value, rtol=1e-6):
    """True when ``text`` contains a number equal to ``value`` (any formatting)."""
    return any(np.isclose(x, value, rtol=rtol, atol=0.0) for x in find_numbers(text))


# ----------------------------------------------------------------------------------------------
# fixtures


@pytest.fixture
def rng():
    return np.random.default_rng(20230517)


@pytest.fixture
def grid44():
    return make_grid(4, 4, 1.0, 1.0)


@pytest.fixture
def sheet():
    """A small 6x5 StretchA3 sheet (1.0 m x 0.8 m, 1 mm, 200 kg/m^3)."""
    v, t = make_grid(6, 5, 1.0, 0.8)
    return membrane(v, t, s0=1e4, bending=1e-3, hourglass=0.5)
