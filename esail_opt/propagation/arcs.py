"""The arc model: one value that says how a segment's closed-form arcs are flown.

Every builder of :mod:`.rectified` and its callers take one :class:`ArcModel`, so that
"the arcs the NLP flew" can be handed on, compared and cached (it is frozen, hence
hashable, as the builders' ``functools.lru_cache`` needs).
"""

from dataclasses import dataclass

from esail_opt.errors import InputError

#: Gauss-Legendre points of each arc's time quadrature in the NLP: its arcs are short,
#: 4 points moved the shipped optima's times by < 1e-4 d at a third more per iteration, and
#: the error control removes what is left.
QUAD_NODES = 2
#: Gauss-Legendre points per panel of the paper's first-order arcs (:data:`FIRST_ORDER`),
#: where one arc may span years.
PANEL_NODES = 8
#: Most Gauss-Legendre points a quadrature may ask for.
MAX_NODES = 64
#: Most rectified arcs in one segment the model accepts (the error control stops far
#: below, at ``optimisation.error_control.MAX_SUB_ARCS``).
SUB_ARCS_LIMIT = 10_000


def _check_flag(name, value):
    if not isinstance(value, bool):
        raise InputError(f"arc_model.{name} = {value!r} is not True or False")


def _check_int(name, value, lo, hi):
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise InputError(f"arc_model.{name} = {value!r} is not a whole number in [{lo}, {hi}]")


@dataclass(frozen=True)
class ArcModel:
    """How the arcs of one constant-pitch segment are flown; the default is exactly what
    the NLP flies (``optimisation.transcription``), the paper's plain rectification is
    :data:`FIRST_ORDER`.  A field outside its range raises InputError naming it.

    Attributes
    ----------
    order : {1, 2}
        1: the paper's first-order arc (Eq. 12); 2 (default): one Picard sweep on it
        (``closed_form.SecondOrderArc``), which flew closer to Eqs. 1-2 in less time on
        the benchmarks' NLPs, extrapolated or not (THEORY.md §3.8).
    invariant : bool
        End every arc with v_theta = h / r, h the exact angular momentum of Eq. 2 at the
        arc's quadrature time (THEORY.md §5.3a).  On by default: a few instructions an
        arc, and never worse on the stored optima.
    extrapolate : bool
        Richardson-extrapolate the segment's chain of arcs (``rectified_function``).
        Off by default: on second-order arcs it gains about what one more sub-arc does,
        at three times the arcs.
    sub_arcs : int
        Rectified arcs chained in each segment, of equal length, in [1, 10000]; default 2,
        the problem files' ``Segments.sub_arcs``.
    nodes : int
        Gauss-Legendre points per panel of the time quadrature, in [1, 64].
    native : bool
        Fly compiled arcs (``propagation.compiled``) where lengths are angles and a
        compiler allows, else CasADi's virtual machine: the speed changes, the numbers
        agree to rounding.
    """

    order: int = 2
    invariant: bool = True
    extrapolate: bool = False
    sub_arcs: int = 2
    nodes: int = QUAD_NODES
    native: bool = True

    def __post_init__(self):
        if isinstance(self.order, bool) or self.order not in (1, 2):
            raise InputError(f"arc_model.order = {self.order!r} is not 1 or 2")
        _check_flag("invariant", self.invariant)
        _check_flag("extrapolate", self.extrapolate)
        _check_flag("native", self.native)
        _check_int("sub_arcs", self.sub_arcs, 1, SUB_ARCS_LIMIT)
        _check_int("nodes", self.nodes, 1, MAX_NODES)

    def one_arc(self):
        """This model with one arc a segment and no extrapolation, as the chain builders
        fly it arc by arc."""
        return ArcModel(self.order, self.invariant, False, 1, self.nodes, self.native)


#: The paper's rectification: one plain first-order arc a segment, no invariant, the
#: 8-point panels, on the virtual machine.
FIRST_ORDER = ArcModel(order=1, invariant=False, extrapolate=False, sub_arcs=1,
                       nodes=PANEL_NODES, native=False)
