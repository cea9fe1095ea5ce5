"""The trace of a registration: every stage's output, for pictures and diagnosis."""

from __future__ import annotations

from dataclasses import dataclass

from meshrec._values import ValueEquality
from meshrec.registration.brackets import PhiBrackets
from meshrec.registration.lookup import ContactCandidates
from meshrec.registration.phi import PhiSearch
from meshrec.registration.poses import PoseHypothesis, RefinedSearch
from meshrec.registration.screening import Screening
from meshrec.registration.searching import Searches

__all__ = ["RegistrationTrace"]


@dataclass(frozen=True, eq=False)
class RegistrationTrace(ValueEquality):
    """The stages' outputs of one registration (``register(..., trace=True)``).

    Attributes
    ----------
    candidates : ContactCandidates
        Stage 1: the lookup's candidates, their sides and frames.
    brackets : PhiBrackets or None
        Stage 2: the sampled error against phi per candidate, its brackets, the ranking
        (None when there was no candidate).
    screening : Screening or None
        Stage 3: the screened candidates, best first.
    phis : tuple of PhiSearch
        Stage 4: the refined phi of each candidate searched, in the order of
        ``screening.candidates``.
    searches : Searches or None
        Stage 5: each local search's start, path and result.
    refinements : tuple of RefinedSearch
        Stage 6: the rigid refinements, least search error first.
    hypotheses : tuple of PoseHypothesis
        Every refined pose, least RMS first, duplicates included (``Registration.poses``
        keeps the distinct ones).
    """

    candidates: ContactCandidates
    brackets: PhiBrackets | None = None
    screening: Screening | None = None
    phis: tuple[PhiSearch, ...] = ()
    searches: Searches | None = None
    refinements: tuple[RefinedSearch, ...] = ()
    hypotheses: tuple[PoseHypothesis, ...] = ()

    def __repr__(self) -> str:
        runs = 0 if self.searches is None else len(self.searches.runs)
        return (
            f"RegistrationTrace(candidates={len(self.candidates)}, searches={runs}, "
            f"refinements={len(self.refinements)})"
        )
