"""Information trackers D_iw(k) of one CU (DMPC-Swarm Sec. 4.2.1, Alg. 2, Lemma 1-2).

D_iw(k) holds every trajectory UAV i may be following during round k, as far
as CU w knows. Alg. 2 is garbled in our copy of the paper; this is its
reconstruction from the prose of Sec. 4.2.1 and the proofs of Appendix C.
In round k's computation phase, with the messages of round k - 1:

0. Late copies (``MlrConfig.repeat_trajectory``, not in the paper): a CU
   message of round k - 1 may carry again the trajectory its CU computed in
   round k - 2. It is added to that UAV's tracker when the tracker is
   deprecated and lacks it (this CU lost the round k - 2 message), before
   step 1, so that the UAV's state message of round k - 1, which names the
   trajectory it follows, restores the tracker. Only deprecated trackers
   (used in no QP) gain candidates, and a restore names the UAV's own
   trajectory, as in step 1: Lemma 1 is untouched.
1. Metadata (Line 6): if UAV i's state message of round k - 1 arrived, it
   names the trajectory i followed in round k - 1; keep only the candidate
   with that metadata. If no candidate has it, the tracker is deprecated.
2. Missing metadata (Line 13): if the state message was lost and the tracker
   holds more than one candidate, the CU cannot tell which one i follows:
   deprecated. With one candidate it stays as it is (Lemma 1's proof).
2b. With ``keep_ambiguous`` (``MlrConfig.keep_ambiguous``): instead of step
   2, a tracker holding at most K candidates (K = ``max_candidates``, the
   old and the new trajectory) stays usable with all of them; it is
   deprecated when step 5 would give it more than K. Every QP constrains the
   computed UAV against every candidate, so the true trajectory is always
   among the constrained ones (Lemma 1 holds). Lemma 2's equality across CUs
   weakens to "each non-deprecated tracker holds the true trajectory", which
   is what the collision argument uses: a CU computes a UAV only when its
   tracker of that UAV holds one candidate (then the true one), so for two
   UAVs computed at once by two CUs both QPs contain the midway constraint of
   the same true pair (Eq. 15); the extra candidate only adds constraints.
   The QP stays sized for K candidates per UAV.
3. Recovery replies: a reply of round k - 1 carries the trajectory i followed
   in round k - 1; the tracker becomes exactly that one, not deprecated.
4. Missing CU messages (Line 18): if a CU slot of round k - 1 is unaccounted
   for (neither a CU message, nor a reply in a donated slot, nor a slot the
   CU knows was donated), a new trajectory for an unknown UAV may be missing:
   every tracker is deprecated.
5. New trajectories (Line 22): every trajectory computed in round k - 1 (by
   this CU, or received from another) is added: i follows it in round k if
   it received it, else its old one, so the tracker keeps both.

Choices where the paper is silent: a deprecated tracker whose UAV later
names (step 1) a candidate the tracker still holds is restored to that
candidate (the metadata identifies it as well as a reply would); step 4
overrides such a restore in the same round. A deprecated tracker keeps adding
new trajectories (step 5, newest ``max_kept`` kept) so that it can be restored
this way. Steps 1-3 run before 4-5 because the metadata of round k - 1 refers
to trajectories followed in round k - 1, before those computed in k - 1 start.

:meth:`InformationTrackers.update_ignoring_loss` is the baseline of Sec. 5.4
(Gräfe et al. 2022): one trajectory per UAV, the newest known, never deprecated.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

from planners.dmpc.mlr.trajectory import ReferenceTrajectory, TrajectoryId

__all__ = ["InformationTrackers", "TrackerEntry", "TrackerUpdate"]


@dataclass(frozen=True)
class TrackerEntry:
    """D_iw for one UAV i.

    Attributes:
        candidates: the trajectories i may follow, oldest first.
        deprecated: True when they may not contain i's true trajectory.
        missing: deprecated, and i's latest state message named a trajectory
            that is not among the candidates: its metadata cannot restore the
            tracker, only a recovery reply (or a later state message naming a
            trajectory added since) can. False when the tracker is only
            deprecated for want of metadata or a CU message.
    """

    candidates: tuple[ReferenceTrajectory, ...]
    deprecated: bool = False
    missing: bool = False

    @property
    def metas(self) -> tuple[TrajectoryId, ...]:
        """Metadata of the candidates, oldest first."""
        return tuple(c.meta for c in self.candidates)


@dataclass(frozen=True)
class TrackerUpdate:
    """What one Alg. 2 update did.

    Attributes:
        newly_deprecated: UAVs whose tracker became deprecated in this update.
        restored: UAVs whose deprecated tracker was restored (reply or metadata).
        all_deprecated: a CU slot was unaccounted for (step 4).
        causes: (cause, UAV) for each newly deprecated tracker, the first step
            that deprecated it: ``"unnamed"`` (step 1: its UAV named a
            trajectory the tracker lacks), ``"ambiguous"`` (step 2: its state
            message was lost and it holds several candidates), ``"slot"``
            (step 4: a CU slot unaccounted for), ``"suspect"`` (step 4b: the
            UAV a missed CU message can have carried) or ``"crowded"``
            (step 2b: more candidates than ``keep_ambiguous`` allows).
    """

    newly_deprecated: tuple[int, ...]
    restored: tuple[int, ...]
    all_deprecated: bool
    causes: tuple[tuple[str, int], ...] = ()


class InformationTrackers:
    """The N information trackers D_iw of CU w (Alg. 2).

    Args:
        initial: N initial trajectories, known to every CU (Remark 2: hover).
        max_kept: most candidates a deprecated tracker keeps (newest first).
    """

    def __init__(self, initial: Sequence[ReferenceTrajectory], max_kept: int = 8) -> None:
        self.entries: list[TrackerEntry] = [TrackerEntry((t,)) for t in initial]
        self.max_kept = int(max_kept)

    def __len__(self) -> int:
        return len(self.entries)

    def __getitem__(self, uav_id: int) -> TrackerEntry:
        return self.entries[uav_id]

    @property
    def deprecated_ids(self) -> tuple[int, ...]:
        """UAVs whose tracker is deprecated."""
        return tuple(i for i, e in enumerate(self.entries) if e.deprecated)

    def deprecate_all(self) -> None:
        """Mark every tracker deprecated (a CU that may have missed trajectories: it joins late)."""
        self.entries = [TrackerEntry(e.candidates, True, e.missing) for e in self.entries]

    @property
    def any_deprecated(self) -> bool:
        """Whether MLR is needed (Alg. 1)."""
        return any(e.deprecated for e in self.entries)

    def update(
        self,
        following: Mapping[int, TrajectoryId],
        new_trajectories: Mapping[int, ReferenceTrajectory],
        replies: Mapping[int, ReferenceTrajectory],
        all_cu_slots_accounted: bool,
        suspects: Iterable[int] = (),
        keep_ambiguous: int = 0,
        late: Mapping[int, ReferenceTrajectory] | None = None,
    ) -> TrackerUpdate:
        """Alg. 2 with the messages of the previous round (steps 1-5 of the module docstring).

        Args:
            following: UAV i -> metadata in its received state message of the previous round.
            new_trajectories: UAV i -> trajectory computed for it in the previous round
                (received from a CU, or computed by this CU).
            replies: UAV i -> trajectory from a received recovery reply of the previous round.
            all_cu_slots_accounted: False if a CU slot of the previous round is missing.
            suspects: UAVs whose tracker is deprecated like in step 4, but alone
                (step 4b): the UAVs a missed CU message can have carried a
                trajectory for, when the caller can name them.
            keep_ambiguous: 0 for the paper's step 2 (Line 13). K >= 2: a tracker
                whose UAV's state message was lost keeps all its candidates, not
                deprecated, as long as it holds at most K of them (step 2b,
                module docstring); one that grows beyond K in step 5 is deprecated.
            late: UAV i -> a trajectory computed two rounds ago, carried again by
                a CU message of the previous round (step 0).
        """
        before = [e.deprecated for e in self.entries]
        cause: dict[int, str] = {}  # the first step that deprecated each tracker that was not
        restored = []
        for i, traj in (late or {}).items():  # step 0
            e = self.entries[i]
            if e.deprecated and all(c.meta != traj.meta for c in e.candidates):
                self.entries[i] = TrackerEntry((e.candidates + (traj,))[-self.max_kept:], True, e.missing)
        for i, entry in enumerate(self.entries):
            if i in replies:  # step 3
                self.entries[i] = TrackerEntry((replies[i],))
                continue
            if i in following:  # step 1 (Line 6)
                match = [c for c in entry.candidates if c.meta == following[i]]
                self.entries[i] = TrackerEntry((match[0],)) if match else TrackerEntry(entry.candidates, True, True)
                if not match:
                    cause.setdefault(i, "unnamed")
            elif len(entry.candidates) > max(keep_ambiguous, 1):  # step 2 (Line 13); 2b keeps up to K
                self.entries[i] = TrackerEntry(entry.candidates, True, entry.missing)
                cause.setdefault(i, "ambiguous")
        if not all_cu_slots_accounted:  # step 4 (Line 18)
            self.entries = [TrackerEntry(e.candidates, True, e.missing) for e in self.entries]
            for i in range(len(self.entries)):
                cause.setdefault(i, "slot")
        for i in suspects:  # step 4b
            self.entries[i] = TrackerEntry(self.entries[i].candidates, True, self.entries[i].missing)
            cause.setdefault(i, "suspect")
        for i, traj in new_trajectories.items():  # step 5 (Line 22)
            e = self.entries[i]
            cands = tuple(c for c in e.candidates if c.meta != traj.meta) + (traj,)
            if e.deprecated:
                cands = cands[-self.max_kept:]
            elif len(cands) > max(keep_ambiguous, 2):  # step 2b: too many to keep usable
                self.entries[i] = TrackerEntry(cands[-self.max_kept:], True, e.missing)
                cause.setdefault(i, "crowded")
                continue
            self.entries[i] = TrackerEntry(cands, e.deprecated, e.missing)
        for i, e in enumerate(self.entries):
            if before[i] and not e.deprecated:
                restored.append(i)
        newly = tuple(i for i, e in enumerate(self.entries) if e.deprecated and not before[i])
        return TrackerUpdate(newly, tuple(restored), not all_cu_slots_accounted, tuple((cause[i], i) for i in newly))

    def update_ignoring_loss(self, new_trajectories: Mapping[int, ReferenceTrajectory]) -> TrackerUpdate:
        """Baseline (Sec. 5.4, Gräfe et al. 2022): assume every UAV got its newest known trajectory."""
        for i, traj in new_trajectories.items():
            self.entries[i] = TrackerEntry((traj,))
        return TrackerUpdate((), (), False)
