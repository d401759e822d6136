"""Distance to the nearest marked cell of a grid: the collision field, the AMCL likelihood field and the costmap's
inflation all start from it (the exact Euclidean distance transform, in the C kernel tb4.core._distance)."""

from __future__ import annotations

import numpy as np

from tb4.core.kernels import load_kernel

__all__ = ["distance_to_marked"]


def distance_to_marked(marked: np.ndarray, cell_size: float = 1.0) -> np.ndarray:
    """For each cell of the 2D boolean grid `marked`, the distance between its centre and the nearest marked cell's
    centre, times `cell_size` (0 on marked cells); inf everywhere when no cell is marked. The same distances as
    scipy.ndimage.distance_transform_edt(~marked) to the last bit with cell_size 1 (within rounding otherwise)."""
    marked = np.ascontiguousarray(marked, dtype=bool)
    if marked.ndim != 2:
        raise ValueError(f"the grid must be 2D, got shape {marked.shape}")
    height, width = marked.shape
    out = np.empty((height, width), dtype=np.float64)
    if marked.size:
        load_kernel("tb4.core._distance").squared(marked.view(np.uint8), height, width, out)
    np.sqrt(out, out=out)
    if cell_size != 1.0:
        out *= cell_size
    return out
