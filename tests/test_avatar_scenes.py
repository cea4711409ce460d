"""The garment scenes of Lu et al. 2023 (Table 1, Fig. 12) at coarse sizes: the mannequin is one
closed mesh, a skirt dropped around its waist lands on its hips and hangs there with no two
triangles intersecting and no vertex inside the avatar, and the builders refuse bad input.
"""

import numpy as np
import pytest
import trimesh

from contact_checks import assert_apart
from peridyn.avatar_scenes import dress, mannequin, skirt


def test_mannequin_is_one_closed_outward_mesh_standing_on_the_ground():
    V, F = mannequin(segments=12)
    mesh = trimesh.Trimesh(V, F, process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert mesh.body_count == 1, "the parts must be united into one body"
    assert mesh.volume > 0.0, "triangles must face outwards"
    assert V[:, 2].max() == pytest.approx(1.75, abs=0.02)
    assert V[:, 2].min() == pytest.approx(0.0, abs=0.005), "the feet stand on z = 0"
    # A person's volume at 1.75 m: tens of litres.
    assert 0.03 < mesh.volume < 0.12


def test_skirt_hangs_from_its_waistband_over_the_hips_without_intersections():
    scene = skirt(around=40, rows=10, resolution=48, dt=2e-3, max_iters=40, threads=1)
    garment = scene.bodies["skirt"]
    avatar = scene.colliders["avatar"]
    contact = scene.solver.contact
    band = garment.pinned
    assert len(band) == 40 and np.all(garment.rest_positions[band, 2] == pytest.approx(1.07))
    assert avatar.signed_distance(garment.positions).min() > contact.thickness + contact.d_hat, \
        "the skirt starts out of contact"
    touched = 0
    for k in range(300):
        scene.solver.step()
        if k % 20 == 19:
            assert_apart([garment], [avatar], contact.thickness, contact.eps)
            touched = max(touched, int((avatar.signed_distance(garment.positions)
                                        < 2 * contact.thickness).sum()))
    x, v = garment.positions, garment.velocities
    assert touched >= 10, "the skirt must come to lie on the hips"
    np.testing.assert_allclose(x[band], garment.rest_positions[band])
    # Its own weight stretches it a few centimetres (24 N/m in-plane stiffness); it swings
    # (implicit Euler barely damps a 1 Hz swing) but gains no speed beyond a fall of that size.
    assert x[:, 2].min() > garment.rest_positions[:, 2].min() - 0.1
    assert np.linalg.norm(v, axis=1).max() < 1.5
    assert np.abs(x[:, :2]).max() < 0.5, "the skirt left the mannequin"


@pytest.mark.parametrize("build, kwargs", [
    (skirt, dict(length=0.0)), (skirt, dict(flare=-0.1)), (skirt, dict(around=2)),
    (dress, dict(rows=1.5)), (dress, dict(gravity=float("nan"))), (dress, dict(xi=-1e-3)),
])
def test_garment_builders_refuse_bad_input(build, kwargs):
    with pytest.raises(ValueError, match=next(iter(kwargs))):
        build(**kwargs)


def test_mannequin_refuses_bad_input():
    with pytest.raises(ValueError, match="segments"):
        mannequin(segments=4)
    with pytest.raises(ValueError, match="height"):
        mannequin(height=-1.0)
