"""How a solve ended: the :class:`Outcome` of an Ipopt return status.

The only reader of Ipopt's status strings, below both ``optimisation.ipopt`` and
``optimisation.pipeline``, so neither imports the other to learn what a status means.
CasADi's ``success`` flag is also true for "Solved_To_Acceptable_Level", so outcomes
are read from ``stats()['return_status']`` and only "Solve_Succeeded" is *converged*.
"""

import enum


class Outcome(enum.Enum):
    """The end of one Ipopt solve; ``value`` is what solution.json writes as ``outcome``."""

    CONVERGED = "converged"
    #: Solved_To_Acceptable_Level: a point worth refining, never reported as converged.
    ACCEPTABLE = "acceptable"
    #: Ipopt's "infeasible" from one start is a local statement, not a proof.
    INFEASIBLE = "infeasible"
    FAILED = "failed"

    @classmethod
    def of(cls, status):
        """The outcome of an Ipopt return status; any status not listed here (iteration
        limit, an evaluation error, a user stop, "unknown") is FAILED."""
        return _OF_STATUS.get(status, cls.FAILED)

    @property
    def converged(self):
        """Only Solve_Succeeded: what exit status 0 and ``"converged": true`` need."""
        return self is Outcome.CONVERGED

    @property
    def found(self):
        """Converged or acceptable: a point the later stages go on from (an acceptable
        one is still not verified)."""
        return self in (Outcome.CONVERGED, Outcome.ACCEPTABLE)


_OF_STATUS = {
    "Solve_Succeeded": Outcome.CONVERGED,
    "Solved_To_Acceptable_Level": Outcome.ACCEPTABLE,
    # Ipopt gave up on feasibility from this start (its restoration phase included).
    "Infeasible_Problem_Detected": Outcome.INFEASIBLE,
    "Restoration_Failed": Outcome.INFEASIBLE,
    "Search_Direction_Becomes_Too_Small": Outcome.INFEASIBLE,
    "Not_Enough_Degrees_Of_Freedom": Outcome.INFEASIBLE,
}
