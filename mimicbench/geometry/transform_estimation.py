"""Per-keypoint transforms of a posed mesh by one joint fit over all bones.

Given rest vertices V (N, 3), rest keypoints C (K, 3), skin weights W (N, K) and posed vertices
P (N, 3), find every bone's rotation R_k and translation t_k (the posed keypoint, DESIGN.md's
convention) minimising the linear-blend-skinning residual of all vertices at once::

    E(R, t) = sum_i || sum_k W_ik (R_k (vbar_i - cbar_k) + t_k) - p_i ||^2
              + ridge * sum_k s_k (rho_k^2 ||log(R_k R0_k^T)||^2 + ||t_k - t0_k||^2)

where (R0_k, t0_k) is bone k's own weighted Kabsch estimate (:mod:`mimicbench.geometry.kabsch`), s_k its
total skin weight and rho_k the weighted spread of its rest vertices (so the ridge is ``ridge``
times the curvature of the per-bone Kabsch objective: it only decides what the mesh leaves
undetermined). The fit has three steps:

1. linear least squares over the K affine maps at once (one sparse factorisation per rig,
   reused for every frame), with the same ridge towards the Kabsch maps;
2. each affine map's linear part projected onto the nearest rotation (polar decomposition);
3. Levenberg-Marquardt on E over all rotations and translations together (sparse normal
   equations, a few iterations), skipped when step 2 already matches the mesh to float32
   rounding.

On a mesh posed by LBS with the same rig, E has its minimum at the transforms it was posed with,
so the fit recovers them to float precision; per-bone Kabsch does not where vertices blend bones.
On a mesh that no rig poses exactly, step 3 adds a prior towards Kabsch scaled by the residual's
variance (:data:`PRIOR_DEG`): fitted freely, blended bones trade rotation against each other's
noise.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix, issparse

from mimicbench.geometry.kabsch import kabsch_rotations, weight_matrix
from mimicbench.geometry.kinematics import transforms_to_array
from mimicbench.geometry.quaternion import matrix_to_quat, quat_to_matrix
from mimicbench.geometry.validation import check_shape
from mimicbench.schemas.weights import SparseWeights, as_dense

RIDGE = 1e-8
"""Weight of the pull towards each bone's Kabsch estimate, relative to the curvature of its own
Kabsch objective (see the module docstring)."""

MIN_SPREAD = 1e-3
"""A bone is supported when its weighted rest vertices spread over at least this fraction of the
rest mesh's bounding-box diagonal in two directions (:func:`weight_support`)."""

ITERATIONS = 10
"""Most Levenberg-Marquardt iterations of step 3."""

PRIOR_DEG = 0.5
"""On a mesh the fit cannot match to float rounding (a prediction, not an LBS pose), each bone's
rotation is pulled towards its Kabsch estimate with weight sigma^2 / tau^2, sigma^2 the variance
per coordinate of the affine step's residual and tau this many degrees (a Gaussian prior of spread tau around Kabsch,
and its translation likewise with tau times the bone's spread): where vertices blend bones the
data alone trades one bone's rotation for its neighbour's noise. An exact LBS pose has sigma at
rounding and is not pulled."""

STOP = 1e-6
"""Step 3 stops once an iteration lowers the objective by less than this fraction, or once no
rotation moves by more than 1e-6 rad and no translation by more than 1e-6 of the rest mesh's
bounding-box diagonal."""


def estimate_transforms(
    rest_vertices: np.ndarray,
    posed_vertices: np.ndarray,
    weights,
    rest_keypoints: np.ndarray,
    min_weight: float = 1e-8,
    ridge: float = RIDGE,
    iterations: int = ITERATIONS,
    prior_deg: float = PRIOR_DEG,
) -> tuple[np.ndarray, np.ndarray]:
    """Estimate every keypoint's transform by the joint fit of all bones (module docstring).

    Args:
        rest_vertices: (N, 3) rest vertices, metres.
        posed_vertices: (..., N, 3) posed vertices, metres (frames batch over leading dimensions).
        weights: dense (N, K) or :class:`~mimicbench.schemas.weights.SparseWeights`, rows summing to 1.
        rest_keypoints: (K, 3) rest keypoints cbar_k, metres.
        min_weight: a keypoint whose total weight is at most this owns no vertices.
        ridge: weight of the pull towards each bone's Kabsch estimate (:data:`RIDGE`), >= 0.
        iterations: most Levenberg-Marquardt iterations, >= 0.
        prior_deg: spread (degrees) of the prior towards per-bone Kabsch on a mesh that no rig
            poses exactly (:data:`PRIOR_DEG`); 0 switches it off.

    Returns:
        transforms (..., K, 7) float32 (q_w, q_x, q_y, q_z, t_x, t_y, t_z) and ``supported`` (K,)
        bool (:func:`weight_support`). A keypoint that owns no vertices gets the identity
        rotation and ``t_k = cbar_k``; one that owns vertices but is not supported (fewer than
        three non-collinear vertices) gets the fit's value, which its ridge keeps at the Kabsch
        estimate about the directions the mesh does not determine. Callers replace both from
        the skeleton (:func:`mimicbench.geometry.pose_readoff.read_pose`).
    """
    rest = check_shape(rest_vertices, (None, 3), "rest_vertices").astype(np.float64)
    posed = np.asarray(posed_vertices, dtype=np.float64)
    if posed.shape[-2:] != rest.shape:
        raise ValueError(f"posed_vertices: expected shape (..., {rest.shape[0]}, 3), got {posed.shape}")
    keypoints = check_shape(rest_keypoints, (None, 3), "rest_keypoints").astype(np.float64)
    if ridge < 0 or iterations < 0 or prior_deg < 0:
        raise ValueError(f"ridge, iterations, prior_deg: expected >= 0, got {ridge}, {iterations}, {prior_deg}")
    w = weight_matrix(weights, keypoints.shape[0])
    q0, t0, _ = kabsch_rotations(rest, posed, w, keypoints, min_weight)
    design, supported = _design_of(rest_vertices, weights, rest_keypoints, rest, w, keypoints, min_weight, ridge)
    lead = posed.shape[:-2]
    q, t = q0.reshape(-1, len(keypoints), 4).copy(), t0.reshape(-1, len(keypoints), 3).copy()
    for f, frame in enumerate(posed.reshape(-1, rest.shape[0], 3)):
        if len(design.bones):
            qa, ta = design.fit(frame, q[f, design.bones], t[f, design.bones], iterations, prior_deg)
            q[f, design.bones], t[f, design.bones] = qa, ta
    return transforms_to_array(q.reshape(lead + q.shape[1:]), t.reshape(lead + t.shape[1:])), supported


_DESIGNS: dict = {}
"""Recent rigs' fit designs, keyed by the identity of their read-only input arrays
(:func:`_design_of`)."""

DESIGN_CACHE = 16
"""How many rigs' designs :func:`_design_of` keeps."""


def _frozen_owner(array) -> np.ndarray | None:
    """The ndarray owning ``array``'s memory when it and every array it views are read-only (so
    its content cannot change while the owner lives), else None."""
    a = array
    while isinstance(a, np.ndarray):
        if a.flags.writeable:
            return None
        if a.base is None:
            return a
        a = a.base
    return None


def _design_of(rest_in, weights_in, keypoints_in, rest, w, keypoints, min_weight, ridge):
    """``(_Design, supported)`` of a rig, reused across calls when the caller's rest vertices,
    keypoints and sparse weights are read-only arrays (as every :class:`mimicbench.benchmark.request.Rig`'s
    are): the cache holds those arrays, so their identities stay unique while cached."""
    from mimicbench.schemas.weights import SparseWeights

    owners = [_frozen_owner(a) for a in (rest_in, keypoints_in)]
    if isinstance(weights_in, SparseWeights):
        owners += [_frozen_owner(weights_in.indices), _frozen_owner(weights_in.values)]
    else:
        owners.append(None)
    key = None
    if all(o is not None for o in owners):
        views = (rest_in, keypoints_in, weights_in.indices, weights_in.values)
        key = tuple((id(o), np.asarray(v).__array_interface__["data"][0], np.shape(v), np.asarray(v).strides,
                     np.asarray(v).dtype.str) for o, v in zip(owners, views)) + (min_weight, ridge)
        if key in _DESIGNS:
            _, design, supported = _DESIGNS[key]
            return design, supported.copy()
    design = _Design.of(rest, w, keypoints, min_weight, ridge)
    supported = weight_support(rest, w, min_weight)
    if key is not None:
        while len(_DESIGNS) >= DESIGN_CACHE:
            _DESIGNS.pop(next(iter(_DESIGNS)))
        _DESIGNS[key] = (owners, design, supported.copy())
    return design, supported


def weight_support(rest_vertices: np.ndarray, weights, min_weight: float = 1e-8,
                   min_spread: float = MIN_SPREAD) -> np.ndarray:
    """(K,) bool: the bones whose rotation the mesh determines.

    Bone k is supported when its total weight exceeds ``min_weight`` and its rest vertices,
    weighted by W_ik, spread in at least two directions: the second largest eigenvalue of their
    weighted covariance is at least ``(min_spread * diagonal)^2``, ``diagonal`` the rest mesh's
    bounding-box diagonal (a bone with one vertex, or vertices on a line, leaves its rotation
    about that line free).

    Args:
        rest_vertices: (N, 3) rest vertices, metres.
        weights: dense (N, K), scipy sparse (N, K) or :class:`~mimicbench.schemas.weights.SparseWeights`.
        min_weight: smallest total weight that counts as owning vertices.
        min_spread: spread threshold as a fraction of the bounding-box diagonal.
    """
    rest = check_shape(rest_vertices, (None, 3), "rest_vertices").astype(np.float64)
    if isinstance(weights, SparseWeights):
        wt = weights.to_csr().T.tocsr()  # (K, N)
    elif issparse(weights):
        wt = csr_matrix(weights, dtype=np.float64).T.tocsr()
    else:
        wt = csr_matrix(as_dense(weights).T)
    total = np.asarray(wt.sum(axis=1)).ravel()
    owned = total > min_weight
    safe = np.where(owned, total, 1.0)
    mu = np.asarray(wt @ rest) / safe[:, None]
    second_moment = np.asarray(wt @ (rest[:, :, None] * rest[:, None, :]).reshape(-1, 9)).reshape(-1, 3, 3)
    cov = second_moment / safe[:, None, None] - np.einsum("ka,kb->kab", mu, mu)
    second = np.linalg.eigvalsh(cov)[:, 1]
    diagonal = float(np.linalg.norm(rest.max(axis=0) - rest.min(axis=0))) if len(rest) else 0.0
    return owned & (second >= (min_spread * diagonal) ** 2)


def _entries(weights, min_weight: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Non-zero skin weights of the sparse (N, K) ``weights``: vertex (E,), bone (E,), weight (E,),
    and the bones that own vertices (A,)."""
    coo = weights.tocoo()
    owners = np.flatnonzero(np.asarray(weights.sum(axis=0)).ravel() > min_weight)
    keep = (coo.data > 0) & np.isin(coo.col, owners)
    return coo.row[keep].astype(np.int64), coo.col[keep].astype(np.int64), coo.data[keep], owners


@dataclass
class _Design:
    """What the fit of one rig shares across frames: E non-zero weights (vertex ``vertex``, index
    into ``bones`` ``slot``, weight ``w``, rest offset ``u`` = vbar_i - cbar_k (E, 3)), the A owning
    bones ``bones`` with total weight ``total`` (A,) and squared spread ``rho2`` (A,), the ridge, the
    factorised normal matrix of the affine step and the blend matrix ``blend`` (N, E)."""

    vertex: np.ndarray
    slot: np.ndarray
    w: np.ndarray
    u: np.ndarray
    bones: np.ndarray
    total: np.ndarray
    rho2: np.ndarray
    ridge: float
    affine_solve: object
    affine_design: object
    blend: object
    jac: object
    jac_from: np.ndarray
    jac_t: object
    jac_t_from: np.ndarray
    step_tol: np.ndarray

    @classmethod
    def of(cls, rest: np.ndarray, weights, keypoints: np.ndarray, min_weight: float, ridge: float) -> "_Design":
        from scipy.sparse import csc_matrix, diags
        from scipy.sparse.linalg import factorized

        vertex, bone, w, bones = _entries(weights, min_weight)
        slot = np.searchsorted(bones, bone)
        a, n, e = len(bones), len(rest), len(vertex)
        u = rest[vertex] - keypoints[bone]
        total = np.bincount(slot, weights=w, minlength=a)
        mu = np.stack([np.bincount(slot, weights=w * rest[vertex, c], minlength=a) for c in range(3)], -1)
        mu /= np.maximum(total, 1e-300)[:, None]
        spread = np.bincount(slot, weights=w * ((rest[vertex] - mu[slot]) ** 2).sum(-1), minlength=a)
        diagonal = float(np.linalg.norm(rest.max(axis=0) - rest.min(axis=0))) if n else 1.0
        rho2 = spread / np.maximum(total, 1e-300) + (1e-6 * diagonal) ** 2
        # Affine step: vertex i = sum_e w_e [u_e, 1] X_slot(e), X_a (4, 3) = [L_a^T; t_a^T].
        design = csr_matrix((np.concatenate([w[:, None] * u, w[:, None]], 1).ravel(),
                             (np.repeat(vertex, 4), (4 * slot[:, None] + np.arange(4)).ravel())), shape=(n, 4 * a))
        reg = ridge * np.repeat(total, 4) * np.tile([1.0, 1.0, 1.0, 0.0], a)
        reg = reg * np.repeat(rho2, 4) + ridge * np.repeat(total, 4) * np.tile([0.0, 0.0, 0.0, 1.0], a)
        normal = (design.T @ design + diags(reg + 1e-300)).tocsc()
        blend = csr_matrix((w, (vertex, np.arange(e))), shape=(n, e))
        # Jacobian pattern of step 3: per entry 9 rotation and 3 translation non-zeros.
        rows_rot = (3 * vertex[:, None, None] + np.arange(3)[None, :, None]).repeat(3, axis=2)
        cols_rot = (6 * slot[:, None, None] + np.arange(3)[None, None, :]).repeat(3, axis=1)
        rows_t = 3 * vertex[:, None] + np.arange(3)
        cols_t = 6 * slot[:, None] + 3 + np.arange(3)
        jac_rows = np.concatenate([rows_rot.reshape(e, 9), rows_t], 1).ravel()
        jac_cols = np.concatenate([cols_rot.reshape(e, 9), cols_t], 1).ravel()
        # The Jacobian and its transpose keep one sparsity pattern: build both once, with where
        # each non-zero comes from, and refill their data at each iteration.
        order = np.arange(1, len(jac_rows) + 1, dtype=np.float64)
        jac = csr_matrix((order, (jac_rows, jac_cols)), shape=(3 * n, 6 * a))
        jac_t = csr_matrix((order, (jac_cols, jac_rows)), shape=(6 * a, 3 * n))
        return cls(vertex, slot, w, u, bones, total, rho2, ridge, factorized(csc_matrix(normal)), design, blend,
                   jac, jac.data.astype(np.int64) - 1, jac_t, jac_t.data.astype(np.int64) - 1,
                   np.repeat([1e-6, 1e-6 * diagonal], 3))

    def fit(self, posed: np.ndarray, q0: np.ndarray, t0: np.ndarray, iterations: int,
            prior_deg: float) -> tuple[np.ndarray, np.ndarray]:
        """Quaternions (A, 4) and positions (A, 3) of the owning bones for one frame ``posed``
        (N, 3), from their Kabsch estimates ``q0`` (A, 4), ``t0`` (A, 3)."""
        r0 = quat_to_matrix(q0)
        # Step 1: affine least squares with the ridge towards Kabsch.
        lam = self.ridge * self.total
        rhs = np.asarray(self.affine_design.T @ posed).reshape(-1, 4, 3)
        rhs[:, :3] += (lam * self.rho2)[:, None, None] * r0.transpose(0, 2, 1)
        rhs[:, 3] += lam[:, None] * t0
        x = np.stack([self.affine_solve(np.ascontiguousarray(rhs.reshape(-1, 3)[:, c])) for c in range(3)], -1)
        affine_residual = float(((np.asarray(self.affine_design @ x) - posed) ** 2).sum())
        x = x.reshape(-1, 4, 3)
        # Step 2: the nearest rotation to each linear part.
        r = _nearest_rotation(x[:, :3].transpose(0, 2, 1))
        t = x[:, 3].copy()
        # Step 3: Levenberg-Marquardt on all rotations and translations together, unless the mesh
        # is already matched to float32 rounding (an exact LBS pose: the affine step solved it).
        rounding2 = (4.0 * float(np.finfo(np.float32).eps) * float(np.abs(posed).max(initial=0.0))) ** 2 * len(posed)
        pull = (lam * self.rho2, lam)
        # A mesh no rig poses exactly: the affine fit's residual variance sigma^2 per coordinate sets
        # a prior towards Kabsch, sigma^2 / tau^2 on each rotation's deviation (tau = prior_deg).
        if prior_deg > 0 and affine_residual > rounding2:
            w = affine_residual / max(3 * len(posed) - 12 * len(self.bones), 1) / np.radians(prior_deg) ** 2
            pull = (pull[0] + w, pull[1] + w / self.rho2)
        r, t, _ = self._refine(posed, r, t, r0, t0, pull, iterations, rounding2)
        return matrix_to_quat(r), t

    def _objective(self, posed, r, t, r0, t0, pull):
        res = self._residual(posed, r, t)
        log = _rotation_log(np.einsum("aij,akj->aik", r, r0))
        value = (res ** 2).sum() + (pull[0] * (log ** 2).sum(-1) + pull[1] * ((t - t0) ** 2).sum(-1)).sum()
        return value, res, log

    def _residual(self, posed, r, t):
        moved = np.einsum("eij,ej->ei", r[self.slot], self.u) + t[self.slot]  # (E, 3)
        return np.asarray(self.blend @ moved) - posed

    def _refine(self, posed, r, t, r0, t0, pull, iterations, rounding2):
        """Levenberg-Marquardt from rotations r (A, 3, 3) and positions t (A, 3) on the residual plus
        ``pull`` = (rotation weights (A,), translation weights (A,)) times the squared deviations from
        Kabsch's r0, t0; returns r, t and the vertex residual (N, 3)."""
        from scipy.sparse import diags

        a = len(self.bones)
        prior = np.stack([pull[0]] * 3 + [pull[1]] * 3, -1).ravel()  # (6A,)
        value, res, log = self._objective(posed, r, t, r0, t0, pull)
        if (res ** 2).sum() <= rounding2:
            return r, t, res
        damping = 1e-8
        for _ in range(iterations):
            ru = np.einsum("eij,ej->ei", r[self.slot], self.u)  # R_k u_e, (E, 3)
            x, y, z = ru.T
            zero = np.zeros_like(x)
            # d(moved)/d(omega) = -[R u]_x for the world-frame increment R <- exp(omega) R.
            minus_cross = np.stack([zero, z, -y, -z, zero, x, y, -x, zero], -1)
            data = np.concatenate([self.w[:, None] * minus_cross, np.repeat(self.w[:, None], 3, 1)], 1).ravel()
            jac, jac_t = self.jac.copy(), self.jac_t.copy()
            jac.data, jac_t.data = data[self.jac_from], data[self.jac_t_from]
            hess = jac_t @ jac
            grad = jac_t @ res.ravel() + prior * np.concatenate([log, t - t0], 1).ravel()
            diag = hess.diagonal() + prior
            improved = small = False
            for _ in range(8):
                step = -_solve_spd(hess + diags(prior + damping * diag + 1e-300), grad).reshape(a, 6)
                r_new = _rotation_exp(step[:, :3]) @ r
                t_new = t + step[:, 3:]
                new_value, new_res, new_log = self._objective(posed, r_new, t_new, r0, t0, pull)
                if new_value <= value * (1.0 + STOP):  # no worse, up to rounding
                    improved = True
                    r, t, res, log = r_new, t_new, new_res, new_log
                    small = value - new_value <= STOP * max(value, 1e-300)
                    value = new_value
                    damping = max(damping * 0.1, 1e-12)
                    break
                damping *= 100.0
            if not improved or small or (np.abs(step) < self.step_tol).all():
                break
        return r, t, res


DENSE_SOLVE = 3000
"""Normal equations up to this many unknowns are solved densely (Cholesky), larger ones sparsely."""


def _solve_spd(matrix, rhs: np.ndarray) -> np.ndarray:
    """Solve the symmetric positive definite sparse system ``matrix`` (n, n) x = ``rhs`` (n,)."""
    from scipy.linalg import LinAlgError, cho_factor, cho_solve
    from scipy.sparse.linalg import spsolve

    if matrix.shape[0] <= DENSE_SOLVE:
        try:
            return cho_solve(cho_factor(matrix.toarray(), check_finite=False), rhs, check_finite=False)
        except LinAlgError:
            pass
    return spsolve(matrix.tocsc(), rhs, permc_spec="MMD_AT_PLUS_A")


def _nearest_rotation(m: np.ndarray) -> np.ndarray:
    """The rotations (A, 3, 3) nearest to matrices m (A, 3, 3) in the Frobenius norm (polar factor,
    with the sign of the smallest singular direction flipped where det < 0)."""
    u, _, vt = np.linalg.svd(m)
    d = np.sign(np.linalg.det(u @ vt))
    d = np.where(d == 0, 1.0, d)
    u = u.copy()
    u[:, :, 2] *= d[:, None]
    return u @ vt


def _rotation_exp(omega: np.ndarray) -> np.ndarray:
    """Rotation matrices (A, 3, 3) of rotation vectors omega (A, 3) (Rodrigues)."""
    angle = np.linalg.norm(omega, axis=-1)
    half = 0.5 * angle
    scale = np.where(angle > 1e-12, np.sin(half) / np.maximum(angle, 1e-300), 0.5)
    q = np.concatenate([np.cos(half)[:, None], scale[:, None] * omega], -1)
    return quat_to_matrix(q)


def _rotation_log(m: np.ndarray) -> np.ndarray:
    """Rotation vectors (A, 3) of rotation matrices m (A, 3, 3), angles in [0, pi]."""
    q = matrix_to_quat(m)  # w >= 0
    s = np.linalg.norm(q[:, 1:], axis=-1)
    angle = 2.0 * np.arctan2(s, q[:, 0])
    scale = np.where(s > 1e-12, angle / np.maximum(s, 1e-300), 2.0)
    return scale[:, None] * q[:, 1:]
