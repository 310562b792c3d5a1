"""The coupling graph of a formation and its error chi (:class:`FormationGraph`, :func:`formation_error`).

A formation is N drones with slot positions c_i (world frame, ENU, [m]) around
a common centre and an undirected graph of edges {i, j}. Edge {i, j} wants
the relative position

    d_ij = c_i - c_j = desired (p_i - p_j)        [m],   d_ji = -d_ij,

which is the offset of the formation cost q_f ||(p_i - p_j) - d_ij||^2
(:mod:`planners.dmpc.admm.ocp`). NOTE the sign: :class:`DmpcConfig`'s
``formation_offsets`` are p_j - p_i; here d_ij is p_i - p_j, as the formation
term is written.

The graph is the paper's coupling graph, and by its Assumption 1 also the
communication graph: N_i^in = N_i^out = the neighbours of i (Stomberg et al.,
Sec. 2.2). An onboard agent gets only its own row of it,
:meth:`FormationGraph.offsets_of`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["FormationGraph", "complete_edges", "formation_error", "polygon_slots", "ring_edges"]


def ring_edges(num_drones: int) -> tuple[tuple[int, int], ...]:
    """Edges {i, i+1 mod N} of a ring (a single edge for N = 2)."""
    n = int(num_drones)
    edges = {tuple(sorted((i, (i + 1) % n))) for i in range(n) if n > 1}
    return tuple(sorted(edges))


def complete_edges(num_drones: int) -> tuple[tuple[int, int], ...]:
    """Every pair {i, j}, i < j."""
    n = int(num_drones)
    return tuple((i, j) for i in range(n) for j in range(i + 1, n))


@dataclass(frozen=True)
class FormationGraph:
    """Slots and undirected edges of a formation.

    Attributes:
        slots_world: (N, 3) slot positions c_i relative to the formation
            centre [m] (world axes).
        edges: (E,) pairs (i, j) with i < j, no duplicates.
    """

    slots_world: np.ndarray
    edges: tuple[tuple[int, int], ...]

    def __post_init__(self) -> None:
        slots = np.array(self.slots_world, dtype=float)
        if slots.ndim != 2 or slots.shape[1] != 3 or slots.shape[0] < 1 or not np.all(np.isfinite(slots)):
            raise ValueError(f"slots_world shape {np.shape(self.slots_world)}: a finite (N, 3) array, N >= 1")
        slots.setflags(write=False)
        object.__setattr__(self, "slots_world", slots)
        n = slots.shape[0]
        edges = tuple((int(i), int(j)) for i, j in self.edges)
        for i, j in edges:
            if not (0 <= i < j < n):
                raise ValueError(f"edges: ({i}, {j}) is not a pair i < j of drones 0..{n - 1}")
        if len(set(edges)) != len(edges):
            raise ValueError("edges: an edge is listed twice")
        object.__setattr__(self, "edges", edges)

    @property
    def num_drones(self) -> int:
        """N."""
        return self.slots_world.shape[0]

    def offset(self, i: int, j: int) -> np.ndarray:
        """(3,) d_ij = c_i - c_j, the desired p_i - p_j [m]."""
        return self.slots_world[i] - self.slots_world[j]

    def offsets_array(self) -> np.ndarray:
        """(E, 3) d_ij of every edge (i, j) in :attr:`edges`."""
        if not self.edges:
            return np.zeros((0, 3))
        i, j = np.array(self.edges).T
        return self.slots_world[i] - self.slots_world[j]

    def neighbours(self, i: int) -> tuple[int, ...]:
        """Sorted neighbour ids of drone ``i`` (N_i^in = N_i^out, Assumption 1)."""
        return tuple(sorted({b for a, b in self.edges if a == i} | {a for a, b in self.edges if b == i}))

    def offsets_of(self, i: int) -> dict[int, np.ndarray]:
        """What drone ``i`` is told: {neighbour id j: d_ij (3,) [m]}."""
        return {j: self.offset(i, j) for j in self.neighbours(i)}

    def references(self, centre_world: np.ndarray) -> np.ndarray:
        """Slot references r_i = centre + c_i: centre (..., 3) -> (..., N, 3) [m]."""
        centre = np.asarray(centre_world, float)
        return centre[..., None, :] + self.slots_world


def formation_error(pos_world: np.ndarray, graph: FormationGraph) -> np.ndarray | float:
    """chi: RMS over the edges of ||(p_i - p_j) - d_ij|| [m].

    chi = sqrt( (1/E) sum_{(i,j)} ||(p_i - p_j) - d_ij||^2 ), 0 for a perfect
    formation (translation-invariant: the formation may sit anywhere).

    Args:
        pos_world: (N, 3) positions, or (T, N, 3) for a time series.
        graph: the formation.

    Returns:
        chi in [m]: a float for (N, 3), (T,) for (T, N, 3).
    """
    p = np.asarray(pos_world, float)
    if p.shape[-2:] != (graph.num_drones, 3):
        raise ValueError(f"pos_world shape {p.shape}: expected (..., {graph.num_drones}, 3)")
    if not graph.edges:
        return np.zeros(p.shape[:-2]) if p.ndim > 2 else 0.0
    i, j = np.array(graph.edges).T
    err = (p[..., i, :] - p[..., j, :]) - graph.offsets_array()
    chi = np.sqrt(np.mean(np.sum(err**2, axis=-1), axis=-1))
    return float(chi) if p.ndim == 2 else chi


def polygon_slots(num_drones: int, radius_m: float, z_m: float = 0.0) -> np.ndarray:
    """(N, 3) slots on a horizontal regular polygon of circumradius ``radius_m`` [m], the first on +x.

    N = 4 gives a square of side sqrt(2) radius_m.
    """
    angle = 2.0 * np.pi * np.arange(int(num_drones)) / int(num_drones)
    return np.stack([radius_m * np.cos(angle), radius_m * np.sin(angle), np.full(angle.shape, float(z_m))], axis=1)
