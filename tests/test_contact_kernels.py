"""Contact kernels against the ipc-toolkit reference (``ipctk``): point-triangle and edge-edge
distances with their gradients, and the additive CCD (Lu et al. 2023, Algorithm 2, line 6).

Thousands of random queries plus degenerate families: parallel and collinear edges, coplanar
point-triangle configurations, zero-length edges, zero motion and touching starts.
"""

import ipctk  # a test dependency (pip install ".[test]"): missing, this module fails
import numpy as np
import pytest

from peridyn._core import contact

N = 2000


def random_cases(rng, n):
    return rng.uniform(-1.0, 1.0, size=(n, 4, 3))


def degenerate_cases(rng, n):
    """Parallel / collinear edges, coplanar points and triangles, repeated vertices."""
    x = random_cases(rng, n)
    k = n // 4
    # Parallel: second edge is the first one shifted (and possibly reversed).
    shift = rng.uniform(-1, 1, size=(k, 3))
    x[:k, 2] = x[:k, 0] + shift
    x[:k, 3] = x[:k, 1] + shift
    x[: k // 2, [2, 3]] = x[: k // 2, [3, 2]]
    # Collinear: every vertex on one line.
    line = rng.uniform(-1, 1, size=(k, 1, 3))
    x[k : 2 * k] = x[k : 2 * k, :1] + rng.uniform(-1, 1, size=(k, 4, 1)) * line
    # Coplanar: everything in z = 0.
    x[2 * k : 3 * k, :, 2] = 0.0
    # Repeated vertices: a zero-length edge / a degenerate triangle.
    x[3 * k :, 1] = x[3 * k :, 0]
    x[3 * k :: 2, 3] = x[3 * k :: 2, 2]
    return x


@pytest.fixture(scope="module")
def cases():
    rng = np.random.default_rng(20231)
    return np.concatenate([random_cases(rng, N), degenerate_cases(rng, N)])


def test_point_triangle_distance_and_gradient_match_ipctk(cases):
    d2, grad = contact.point_triangle_distance(*(cases[:, k] for k in range(4)))
    area = np.linalg.norm(np.cross(cases[:, 2] - cases[:, 1], cases[:, 3] - cases[:, 1]), axis=1)
    generic = np.flatnonzero(area > 1e-6)

    def reference(c, i):
        # ipctk treats a zero-area triangle as a plane (and reports distances to that
        # arbitrary plane); such a triangle is the union of its edges.
        if area[i] > 1e-6:
            return ipctk.point_triangle_distance(*c)
        edges = [(1, 2), (2, 3), (3, 1)]
        return min(ipctk.point_edge_distance(c[0], c[a], c[b]) for a, b in edges)

    ref = np.array([reference(c, i) for i, c in enumerate(cases)])
    np.testing.assert_allclose(d2, ref, rtol=1e-9, atol=1e-12)
    # Gradients where the triangle is not degenerate.
    assert len(generic) > 3000
    ref_grad = np.array([ipctk.point_triangle_distance_gradient(*cases[i]) for i in generic])
    np.testing.assert_allclose(grad[generic], ref_grad, rtol=1e-7, atol=1e-9)


def test_edge_edge_distance_and_gradient_match_ipctk(cases):
    d2, grad = contact.edge_edge_distance(*(cases[:, k] for k in range(4)))

    def reference(c):
        # ipctk assumes edges of nonzero length; a zero-length edge is a point.
        a_point, b_point = np.all(c[0] == c[1]), np.all(c[2] == c[3])
        if a_point and b_point:
            return ipctk.point_point_distance(c[0], c[2])
        if a_point:
            return ipctk.point_edge_distance(c[0], c[2], c[3])
        if b_point:
            return ipctk.point_edge_distance(c[2], c[0], c[1])
        return ipctk.edge_edge_distance(*c)

    ref = np.array([reference(c) for c in cases])
    np.testing.assert_allclose(d2, ref, rtol=1e-9, atol=1e-12)
    ea, eb = cases[:, 1] - cases[:, 0], cases[:, 3] - cases[:, 2]
    sin = np.linalg.norm(np.cross(ea, eb), axis=1) / (
        np.linalg.norm(ea, axis=1) * np.linalg.norm(eb, axis=1) + 1e-300
    )
    generic = np.flatnonzero(sin > 1e-4)
    assert len(generic) >= 2400
    ref_grad = np.array([ipctk.edge_edge_distance_gradient(*cases[i]) for i in generic])
    np.testing.assert_allclose(grad[generic], ref_grad, rtol=1e-7, atol=1e-9)


def ccd_cases(rng, n):
    """Start/end pairs: random, approaching, coplanar, parallel, and zero motion."""
    start = random_cases(rng, n)
    end = start + rng.uniform(-1.5, 1.5, size=(n, 4, 3))
    k = n // 5
    # Head-on: first primitive moves through the second.
    end[:k, :2] = start[:k, :2] + 2.0 * (start[:k, 2:].mean(axis=1, keepdims=True) - start[:k, :2])
    # Coplanar motion in z = 0.
    start[k : 2 * k, :, 2] = 0.0
    end[k : 2 * k, :, 2] = 0.0
    # Parallel edges moving towards each other.
    off = rng.uniform(-1, 1, size=(k, 3))
    start[2 * k : 3 * k, 2:] = start[2 * k : 3 * k, :2] + off[:, None]
    end[2 * k : 3 * k] = start[2 * k : 3 * k]
    end[2 * k : 3 * k, 2:] -= 1.5 * off[:, None]
    # Zero motion.
    end[3 * k : 4 * k] = start[3 * k : 4 * k]
    return start, end


@pytest.mark.parametrize("kind", ["point_triangle", "edge_edge"])
@pytest.mark.parametrize("min_distance", [0.0, 0.05])
def test_additive_ccd_never_misses_a_collision_ipctk_finds(kind, min_distance):
    rng = np.random.default_rng(7 if kind == "edge_edge" else 8)
    start, end = ccd_cases(rng, 1000)
    ours = getattr(contact, f"{kind}_ccd_additive")
    hit, toi = ours(start, end, min_distance)
    # Tight inclusion with a 1e-4 tolerance: exact up to that, and fast enough for thousands.
    ref = ipctk.TightInclusionCCD(tolerance=1e-4, max_iterations=100_000, conservative_rescaling=1.0)
    ref_ccd = getattr(ref, f"{kind}_ccd")
    distance = getattr(ipctk, f"{kind}_distance")
    ref_hit = np.zeros(len(start), bool)
    ref_toi = np.ones(len(start))
    for i in range(len(start)):
        ref_hit[i], ref_toi[i] = ref_ccd(*start[i], *end[i], min_distance=min_distance, tmax=1.0)
    assert ref_hit.sum() > 150, "the cases must exercise collisions"
    missed = np.flatnonzero(ref_hit & ~hit)
    assert missed.size == 0, f"missed {missed.size} collisions, e.g. case {missed[:5]}"
    # Conservative: no later than the reference (up to its tolerance), and the configuration at
    # the reported time still keeps the minimal distance.
    # Tight inclusion itself reports a lower bound, so where ours is later, the distance along
    # the motion up to our time must stay above the minimal distance (sampled densely).
    later = np.flatnonzero(ref_hit & hit & (toi > ref_toi + 1e-3))
    for i in later:
        samples = [distance(*(start[i] + t * (end[i] - start[i]))) for t in np.linspace(0, toi[i], 501)]
        assert min(samples) > min_distance**2, f"case {i}: contact before the reported time"
    for i in np.flatnonzero(hit):
        x = start[i] + toi[i] * (end[i] - start[i])
        initially_apart = distance(*start[i]) > min_distance**2
        if initially_apart:
            assert distance(*x) > min_distance**2
    # Zero motion never reports a collision for pairs that start apart.
    still = np.all(start == end, axis=(1, 2))
    apart = np.array([distance(*s) > min_distance**2 for s in start])
    assert not np.any(hit[still & apart])
    # Not wildly over-conservative: few false positives among pairs the reference clears.
    assert (hit & ~ref_hit).sum() <= 0.2 * ref_hit.sum()
