"""The arc model: one value that says how a segment's closed-form arcs are flown.

Every builder of :mod:`.rectified` and every caller above it (the NLP's segment, the
verification's closed-form curve, the propagation command, the benches) takes one
:class:`ArcModel` instead of a row of flags, so that "the arcs the NLP flew" is a value
that can be handed on, compared and cached (it is frozen, hence hashable, as the
builders' ``functools.lru_cache`` needs).
"""

from dataclasses import dataclass

from esail_opt.errors import InputError

#: Gauss-Legendre points of each arc's time quadrature in the NLP.  Its arcs are short:
#: 4 points left the shipped optima's times of flight unchanged to 1e-4 d at a third more
#: per Ipopt iteration, and what is left of the clock's error the defect correction
#: removes (the error control).
QUAD_NODES = 2
#: Gauss-Legendre points per panel of the paper's first-order arcs (:data:`FIRST_ORDER`):
#: there one arc may span years and its samples double as the quadrature's panels.
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
    """How the arcs of one constant-pitch segment are flown.

    The default is exactly what the NLP flies (``optimisation.transcription``): two
    second-order arcs a segment, each ending on the exact angular momentum, a 2-point
    time quadrature, no extrapolation, compiled where a compiler allows.  A builder that
    is not told otherwise therefore flies the NLP's arcs, and a caller that wants the
    paper's plain first-order rectification says so (:data:`FIRST_ORDER`).

    Attributes
    ----------
    order : {1, 2}
        1: the paper's first-order arc (Eq. 12); 2: one Picard sweep on Eq. 12 over the
        clock's own quadrature nodes (``closed_form.SecondOrderArc``).  Second order is
        the default because on the benchmarks' NLPs it flew closer to Eqs. 1-2 in less
        time than first-order arcs, extrapolated or not (THEORY.md §3.8).
    invariant : bool
        End every arc with v_theta = h / r, h the exact angular momentum of Eq. 2 at the
        arc's quadrature time (THEORY.md §5.3a).  On by default: it costs a few
        instructions an arc and never flew worse on the stored optima.
    extrapolate : bool
        Richardson-extrapolate the segment's chain of arcs: flown as it is and with every
        arc halved, combined as (2^p x_halves - x_whole) / (2^p - 1), p the order.  Off by
        default: on second-order arcs it gains about what one more sub-arc does at the
        same cost (three times the arcs).
    sub_arcs : int
        Rectified arcs chained in each segment, each a sub_arcs-th of its length, in
        [1, 10000].  The default 2 is the problem files' default
        (``Segments.sub_arcs``); the NLP's error control raises it per problem.
    nodes : int
        Gauss-Legendre points per panel of the time quadrature, in [1, 64].
    native : bool
        Fly compiled arcs (``propagation.compiled``) where lengths are angles and a
        compiler allows; elsewhere, and with ``ESAIL_OPT_COMPILE=0``, the same arithmetic
        stays on CasADi's virtual machine.  It changes the speed, never the model: the
        numbers agree to rounding.

    Raises
    ------
    InputError
        A field outside its range, naming the field and the range.
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
        """This model with one arc a segment and no extrapolation: the arc itself, as
        the chain builders fly it arc by arc."""
        return ArcModel(self.order, self.invariant, False, 1, self.nodes, self.native)


#: The paper's rectification: one plain first-order arc a segment, no invariant, the
#: 8-point panels, on the virtual machine.  The ``propagate`` command, the paper's
#: reproduction and the seed's constant-pitch propagation fly it.
FIRST_ORDER = ArcModel(order=1, invariant=False, extrapolate=False, sub_arcs=1,
                       nodes=PANEL_NODES, native=False)
