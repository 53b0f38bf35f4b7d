"""Several separable problems on the same samples, sharing nonlinear parameters by name, as one separable
problem (a joint fit of C_L, C_D and C_m whose separation states are the same).

Each block b keeps its own linear coefficients; the blocks' rows are weighted by sqrt(w_b) and interleaved
sample by sample (row b + B t is block b's sample t), so that a maneuver's rows stay contiguous: the
per-maneuver covariances (``hac-maneuver``, ``cluster``) then see one maneuver as one record across every
coefficient, and the Bartlett weight between two rows is that of their time lag. The regression matrix is
block-diagonal; its derivative columns are the blocks' own, mapped to the shared parameters. The problem
is separable, so :func:`structsearch.engine.fit.fit_problem` solves it by variable projection unchanged.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..data.errors import DeclarationError
from .snls import Evaluation, Reduced, SeparableProblem, project, residual_jacobian


@dataclass(frozen=True, eq=False)
class JointProblem(SeparableProblem):
    """Blocks (each a bound separable problem: ``evaluate``, ``nonlinear_names``, ``linear_names``) over the
    same ``n_samples`` samples, weighted by ``weights``."""

    blocks: tuple
    weights: np.ndarray
    n_samples: int

    def __post_init__(self):
        linear = [n for b in self.blocks for n in b.linear_names]
        twice = sorted({n for n in linear if linear.count(n) > 1})
        if twice:
            raise DeclarationError(f"a joint problem needs distinct linear coefficients; {', '.join(twice)} "
                                   "appear in more than one block")
        if len(self.weights) != len(self.blocks) or not np.all(np.asarray(self.weights) > 0):
            raise DeclarationError("a joint problem needs one positive weight per block")

    @property
    def nonlinear_names(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(n for b in self.blocks for n in b.nonlinear_names))

    @property
    def linear_names(self) -> tuple[str, ...]:
        return tuple(n for b in self.blocks for n in b.linear_names)

    @property
    def units(self) -> dict[str, str]:
        return {n: u for b in self.blocks for n, u in b.units.items()}

    @property
    def n_blocks(self) -> int:
        return len(self.blocks)

    def interleave(self, values: Sequence[np.ndarray]) -> np.ndarray:
        """The blocks' sample vectors as the joint rows (weighted)."""
        out = np.empty(self.n_blocks * self.n_samples)
        for b, v in enumerate(values):
            out[b::self.n_blocks] = np.sqrt(self.weights[b]) * np.asarray(v, float)
        return out

    def block_rows(self, b: int) -> slice:
        return slice(b, self.n_blocks * self.n_samples, self.n_blocks)

    def boundaries(self, boundaries: np.ndarray) -> np.ndarray:
        """The joint rows' maneuver boundaries from the samples' (each maneuver's rows contiguous)."""
        return np.asarray(boundaries, int) * self.n_blocks

    def block_theta(self, b: int, theta: np.ndarray) -> np.ndarray:
        names = self.nonlinear_names
        return np.array([theta[names.index(n)] for n in self.blocks[b].nonlinear_names], float)

    def evaluate(self, theta: np.ndarray) -> Evaluation:
        theta = np.asarray(theta, float)
        names = self.nonlinear_names
        rows_total = self.n_blocks * self.n_samples
        phi = np.zeros((rows_total, len(self.linear_names)))
        dcols, rows, params = [], [], []
        offset = 0
        for b, block in enumerate(self.blocks):
            ev = block.evaluate(self.block_theta(b, theta))
            scale = np.sqrt(self.weights[b])
            where = self.block_rows(b)
            n_lin = len(block.linear_names)
            phi[where, offset:offset + n_lin] = scale * ev.phi
            if ev.dphi.shape[1]:
                d = np.zeros((rows_total, ev.dphi.shape[1]))
                d[where] = scale * ev.dphi
                dcols.append(d)
                rows.append(np.asarray(ev.rows, int) + offset)
                index = np.array([names.index(n) for n in block.nonlinear_names], int)
                params.append(index[np.asarray(ev.params, int)])
            offset += n_lin
        dphi = np.hstack(dcols) if dcols else np.zeros((rows_total, 0))
        return Evaluation(phi, dphi, np.concatenate(rows) if rows else np.zeros(0, int),
                          np.concatenate(params) if params else np.zeros(0, int))

    def jacobian_blocks(self) -> list[tuple[slice, list[int]]]:
        """The non-zero pattern of the model Jacobian [DPhi c, Phi] of :meth:`evaluate`: block b's rows are non-zero
        only in the columns of its nonlinear parameters and of its own linear coefficients (for
        :func:`structsearch.engine.sandwich.scaled_factor`)."""
        names, k = self.nonlinear_names, len(self.nonlinear_names)
        out, offset = [], k
        for b, block in enumerate(self.blocks):
            n_lin = len(block.linear_names)
            out.append((self.block_rows(b), [names.index(n) for n in block.nonlinear_names]
                        + list(range(offset, offset + n_lin))))
            offset += n_lin
        return out

    def reduce(self, theta: np.ndarray, y: np.ndarray) -> Reduced | None:
        """The reduced problem block by block: Phi is block-diagonal, so its projection is each block's own
        (a QR of m_b x n_b per block instead of one of (B m_b) x (sum n_b)), and each block's Golub-Pereyra
        Jacobian fills its rows in the columns of the parameters it has. The rows come block after block,
        not interleaved: the optimiser sees only the residual's norm and J^T J, J^T r, which no row order
        changes, and contiguous blocks are written without strided copies. A test compares the result with
        the stacked problem's."""
        theta = np.asarray(theta, float)
        names = self.nonlinear_names
        m = self.n_samples
        residual = np.empty(self.n_blocks * m)
        jacobian = np.zeros((len(residual), len(names)), order="F")   # column writes; the optimiser QR-s it
        coef = []
        for b, block in enumerate(self.blocks):
            ev = block.evaluate(self.block_theta(b, theta))
            if not (np.all(np.isfinite(ev.phi)) and np.all(np.isfinite(ev.dphi))):
                return None
            # the block's weight scales its rows: project the unweighted rows and scale the residual and the
            # Jacobian (the coefficients do not change), sparing two copies of Phi and its derivative
            scale = np.sqrt(self.weights[b])
            proj = project(ev.phi, y[self.block_rows(b)] / scale)
            jac = residual_jacobian(ev, proj, len(block.nonlinear_names))
            if not np.all(np.isfinite(jac)):
                return None
            rows = slice(b * m, (b + 1) * m)
            residual[rows] = scale * proj.residual
            for j, n in enumerate(block.nonlinear_names):
                jacobian[rows, names.index(n)] = scale * jac[:, j]
            coef.append(proj.coef)
        return Reduced(np.concatenate(coef), residual, jacobian)

    def identifiability(self, theta: np.ndarray) -> dict[str, str]:
        """A shared parameter is not identifiable when no block that has it identifies it (each block's own
        reasons: a state its regressors cannot see, ...); the first block's reason is kept."""
        reasons: dict[str, list[str]] = {}
        having: dict[str, int] = {}
        for b, block in enumerate(self.blocks):
            for n in block.nonlinear_names:
                having[n] = having.get(n, 0) + 1
            for n, why in block.identifiability(self.block_theta(b, theta)).items():
                reasons.setdefault(n, []).append(why)
        return {n: whys[0] for n, whys in reasons.items() if len(whys) == having.get(n, 1)}
