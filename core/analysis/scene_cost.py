"""Whether a scene's Routhian reduction pays: the symbolic work estimated against integrating the part as it is.

Used by :class:`lagrangian.scene.Scene` with ``reduce="auto"``: a pilot run over :data:`PILOT_FRACTION` of the span
counts the unreduced part's evaluations; with the part's size (operations of its tape, counted on the structure, so
that a model given numbers weighs as its symbolic twin does) that gives the cost of integrating it, against the
cost of the reduction.  The reduction is done only when integrating costs more.
"""

from __future__ import annotations

import warnings

from ..errors import LagrangianError
from ..model import Model

#: Cost model, measured on this project's benchmarks: a reduction's symbolic work takes about REDUCE_SECONDS ×
#: (operations of the part) × (eliminated coordinates)² (0.04 s for Kepler's one angle on 39 operations, 0.95 s for
#: a top's two on 121: benchmarks/scenes.py; not counted: SymPy's one-time set-up, about 0.6 s on the first
#: reduction of a process, and a structure reduced before in the process, which reuses its reduction), one
#: evaluation on the tape about TAPE_SECONDS per operation (3 ns on the 4,729 operations of benchmarks/spatial.py's
#: three bodies, more on short tapes, where the trigonometry and the solve weigh more).
REDUCE_SECONDS = 2e-3
TAPE_SECONDS = 5e-9
#: The pilot run that counts the unreduced part's evaluations covers this fraction of the span.
PILOT_FRACTION = 0.02


def reduction_skipped(scene, sub: Model, names: list[str], cyclic: list[str], ops: int) -> str | None:
    """Why the part of ``scene`` on ``names`` (the model ``sub``, ``ops`` operations on the tape of its generic
    equations: a model given numbers weighs as its symbolic twin does) is not reduced through the Routhian, or
    None to eliminate its ignorable coordinates ``cyclic`` (``Scene(reduce=...)``)."""
    if scene.reduce is True:
        return None
    which = ", ".join(cyclic)
    if scene.reduce is False:
        return f"{which} ignorable, not eliminated (reduce=False)"
    symbolic = REDUCE_SECONDS * ops * len(cyclic) ** 2
    t0, t1 = scene.span
    window = (t1 - t0) * PILOT_FRACTION
    inertial = scene._inertial()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            pilot = sub.simulate((t0, t0 + window), initial={n: scene.initial.get(n, 0.0) for n in names},
                                 velocity={n: scene.velocity.get(n, 0.0) for n in names if n in inertial},
                                 params=scene._params_for(sub), method=scene.method, rtol=scene.tol,
                                 atol=scene.tol * 1e-3, points=2, energy_tol=False)
    except LagrangianError:
        return None  # the unreduced part does not run: the reduced one may
    evaluations = pilot.nfev / PILOT_FRACTION
    integration = evaluations * ops * TAPE_SECONDS
    if integration > symbolic:
        return None
    return (f"{which} ignorable, not eliminated: integrating the part as it is costs about {integration:.2g} s "
            f"({evaluations:.2g} evaluations of {ops} operations, counted by a pilot run), the Routhian about "
            f"{symbolic:.2g} s of symbolic work (reduce=True forces it)")
