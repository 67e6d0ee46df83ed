"""Global strain projection of cloth edges (host side, NumPy and SciPy).

A few Newton steps on the edge-length constraints solved together with a sparse direct solve
(Goldenthal et al. 2007, "Efficient simulation of inextensible cloth", their fast projection),
restricted to an upper bound: only edges longer than ``(1 + max_strain)`` times their rest length
take part (an active set re-chosen every Newton step), each is brought to that bound, shorter ones
are left alone. Every vertex carries a 3 x 3 inverse mass: ``w I`` for a free vertex, 0 for a held
one, ``w (I - n n^T)`` for one that may only slide in the plane normal to ``n`` (a vertex a
collider pushes: the correction moves it along the surface, neither into it nor off it).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla


def project_strain(x: np.ndarray, edges: np.ndarray, rest: np.ndarray, inv_mass: np.ndarray,
                   normals: np.ndarray | None, max_strain: float, newton_steps: int,
                   tol: float, damping: float = 1e-9, max_move: float = np.inf) -> tuple[np.ndarray, int]:
    """Positions x (V, 3) projected so that no edge is longer than ``(1 + max_strain)`` times its
    rest length, to within ``tol`` (strain), in at most ``newton_steps`` Newton steps.

    Args:
        x: Positions [m], shape (V, 3); not changed.
        edges: Vertex pairs, shape (E, 2).
        rest: Rest lengths [m], shape (E,).
        inv_mass: Inverse masses, shape (V,): 0 holds a vertex.
        normals: Unit normals, shape (V, 3), of the planes vertices slide in; a zero row: free.
            None: every vertex free.
        max_strain: The bound (>= 0).
        newton_steps: Most Newton steps (>= 1).
        tol: Strain above the bound left once reached.

    Returns:
        The projected positions (a new array) and the Newton steps taken.
    """
    x = np.array(x, dtype=np.float64)
    n_v = len(x)
    w = np.asarray(inv_mass, dtype=np.float64)
    i_all, j_all = edges[:, 0], edges[:, 1]
    bound_all = (1.0 + max_strain) * np.asarray(rest, dtype=np.float64)
    movable = (w[i_all] > 0) | (w[j_all] > 0)
    # the 3 x 3 inverse mass of every vertex as w (I - n n^T), n = 0 for free vertices
    nn = np.zeros((n_v, 3)) if normals is None else np.asarray(normals, dtype=np.float64)
    blocks = w[:, None, None] * (np.eye(3)[None] - nn[:, :, None] * nn[:, None, :])
    rows = np.repeat(np.arange(3 * n_v).reshape(n_v, 3), 3, axis=1).reshape(-1)
    cols = np.tile(np.arange(3 * n_v).reshape(n_v, 3), (1, 3)).reshape(-1)
    wmat = sp.csr_matrix((blocks.reshape(-1), (rows, cols)), shape=(3 * n_v, 3 * n_v))
    active = np.zeros(len(edges), dtype=bool)
    steps = 0
    for steps in range(1, newton_steps + 1):
        d = x[i_all] - x[j_all]
        length = np.linalg.norm(d, axis=1)
        c_all = length - bound_all
        over = movable & (c_all > tol * rest)
        if not over.any():
            return x, steps - 1
        # an edge once over its bound stays in the set (held at the bound) for the rest of the
        # projection, so the set does not flip between Newton steps
        active |= over
        act = np.nonzero(active)[0]
        i, j = i_all[act], j_all[act]
        nrm = d[act] / length[act, None]
        k = len(act)
        # J: one row per active edge, +n at i, -n at j
        jr = np.repeat(np.arange(k), 6)
        jc = np.concatenate([3 * i[:, None] + np.arange(3), 3 * j[:, None] + np.arange(3)], axis=1).reshape(-1)
        jv = np.concatenate([nrm, -nrm], axis=1).reshape(-1)
        jac = sp.csr_matrix((jv, (jr, jc)), shape=(k, 3 * n_v))
        jw = jac @ wmat
        a = (jw @ jac.T).tocsc()
        # a small diagonal term keeps dependent constraints (a triangle's three edges) solvable
        dg = a.diagonal()
        a = a + sp.diags(damping * dg + 1e-12 * max(float(dg.max()), 1e-30))
        lam = spla.spsolve(a, c_all[act])
        dx = (jw.T @ lam).reshape(n_v, 3)
        big = float(np.sqrt((dx * dx).sum(axis=1).max()))
        x -= dx * min(1.0, max_move / big) if big > 0 else 0.0
    return x, steps
