"""Scenes shared by the fluid test modules."""

import numpy as np


def blob_under_a_ceiling(n, h, spacing):
    """An n x n x h blob of cell-centred lattice particles (spacing in m) hanging from a
    ceiling of two layers one spacing wider on every side, at z = 0 and above. Returns the
    positions (m) and the mask of the ceiling's particles (to pin as ghosts)."""
    axes = [np.arange(-1, n + 1), np.arange(-1, n + 1), np.arange(-h, 2)]
    x = (np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3) + 0.5) * spacing
    k = np.floor(x / spacing).astype(int)
    ceiling = k[:, 2] >= 0
    keep = ceiling | ((k[:, 0] >= 0) & (k[:, 0] < n) & (k[:, 1] >= 0) & (k[:, 1] < n))
    return x[keep], ceiling[keep]
