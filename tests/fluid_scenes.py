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


PARTING_GAP = 2.2  # spacings between consecutive depths that count as a parting (honey.md)


def hanging_slabs(depth):
    """The liquid still hanging from a ceiling's film, given each particle's depth below the
    ceiling's lowest layer (spacings): the particles above the first gap of more than
    ``PARTING_GAP`` spacings between consecutive depths (all of them before the blob parts).
    Returns their indices and their slabs, centred on the rest layers (slab j holds depths
    j + 0.5 .. j + 1.5; slab 0 is the film)."""
    order = np.argsort(depth)
    gaps = np.flatnonzero(np.diff(depth[order]) > PARTING_GAP)
    keep = order[: gaps[0] + 1] if gaps.size else order
    return keep, np.clip(np.floor(depth[keep] - 0.5).astype(int), 0, None)


def widest_pair(counts):
    """The index into ``counts[1:-1]`` of the lowest widest pair of neighbouring slabs below the
    film (slabs ``k + 1`` and ``k + 2``), and the pairs' mean counts: the drop's widest part,
    read on pairs so that a stretched layer falling across a slab's edge does not read as a
    thin slab. ``counts`` (more than two slabs) are the particles per slab of
    :func:`hanging_slabs`."""
    pairs = 0.5 * (counts[1:-1] + counts[2:])
    return pairs.size - 1 - int(np.argmax(pairs[::-1])), pairs


def neck_slabs(counts, layer):
    """The length of the neck drawn between the film and the hanging liquid's widest part
    (:func:`widest_pair`), in slabs: the slabs from the film's next one down to that part
    holding liquid, at most a quarter of a full layer of ``layer`` particles (an empty slab is
    a gap opening, not a neck: whole layers drifting apart would read as one)."""
    if counts.size <= 2:
        return 0
    widest, _ = widest_pair(counts)
    between = counts[1: widest + 1]
    return int(((between > 0) & (between <= layer / 4)).sum())
