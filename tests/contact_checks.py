"""Geometric checks of contact results, shared by the contact tests: the package's
:mod:`peridyn.checks` (exact triangle-triangle intersection with ipctk, the smallest distance
between non-adjacent primitives, all bodies' meshes in one numbering) and the promises of the
local step at one instant. The intersection test needs ipctk, a test dependency
(``pip install ".[test]"``): without it the tests fail, naming it, rather than skip.
"""

from peridyn.checks import intersecting_pairs, mesh_of, min_separation

__all__ = ["assert_apart", "intersecting_pairs", "mesh_of", "min_separation"]


def assert_apart(bodies, colliders, thickness, eps):
    """The promises of the contact local step at one instant: no two non-adjacent triangles
    of `bodies` intersect, non-adjacent primitives are at least `eps * thickness` apart, and
    no vertex is inside a collider (static colliders)."""
    x, tris, _ = mesh_of(bodies)
    assert not intersecting_pairs(x, tris), "triangles intersect"
    gap = min_separation(x, tris, 2 * thickness)
    assert gap >= eps * thickness, f"primitives {gap:.3g} m apart, < eps xi"
    for collider in colliders:
        depth = collider.signed_distance(x).min()
        assert depth > -1e-6, f"a vertex is {-depth:.3g} m inside {collider!r}"
