"""Whether a scene's Routhian reduction pays: the symbolic work estimated against integrating the part as it is.

Used by :class:`lagrangian.scene.Scene` with ``reduce="auto"``.  The reduction's symbolic work is estimated from
the part's size (operations of its tape, counted on the structure, so that a model given numbers weighs as its
symbolic twin does) and the coordinates it would eliminate; divided by the cost of one evaluation, that is the
*break-even*: the evaluations of the part as it is that cost what its reduction would.  The part is then run as it
is, over the whole span, with the break-even as its budget (``Model.simulate(max_evaluations=...)``, judged on the
run's pace from 131,072 evaluations on):

* a run that ends within it is the part's solution: the scene keeps it, and :meth:`Scene.run` returns it without
  integrating again.  A scene that rightly declines the reduction costs what the full model costs, with no pilot
  run on top (a pilot over 2 % of the span cost Kepler's orbit 2 % of its run; ``benchmarks/scenes.py``);
* a run that at its pace would need more is stopped, and the part is reduced.  What it spent is never more than
  the break-even (its projection passes the budget before its count does), about a third of it for a run at a
  steady pace (131,072 of at least 400,000 evaluations), so deciding costs at most what the reduction it decides
  on costs, usually a third; a long run is stopped after a small share of it.

The plan is made when first read, so ``Scene.report()`` before ``Scene.run()`` makes that run (within the
break-even); with ``progress``, a run stopped at the break-even reports part of the span before the reduced run
reports its own.
"""

from __future__ import annotations

import warnings

from ..errors import LagrangianError

#: Cost model, measured on this project's benchmarks: a reduction's symbolic work takes about REDUCE_SECONDS ×
#: (operations of the part) × (eliminated coordinates)² (0.04 s for Kepler's one angle on 39 operations, 0.95 s for
#: a top's two on 121: benchmarks/scenes.py; not counted: SymPy's one-time set-up, about 0.6 s on the first
#: reduction of a process, and a structure reduced before in the process, which reuses its reduction), one
#: evaluation on the tape about TAPE_SECONDS per operation (3 ns on the 4,729 operations of benchmarks/spatial.py's
#: three bodies, more on short tapes, where the trigonometry and the solve weigh more).
REDUCE_SECONDS = 2e-3
TAPE_SECONDS = 5e-9


def break_even(eliminated: int) -> float:
    """Evaluations of a part that cost what eliminating ``eliminated`` of its coordinates would: the operations of
    the part cancel (``REDUCE_SECONDS · ops · n² = evaluations · ops · TAPE_SECONDS``)."""
    return REDUCE_SECONDS * eliminated ** 2 / TAPE_SECONDS


def reduction_skipped(scene, part, cyclic: list[str]) -> str | None:
    """Why ``part`` of ``scene`` (unreduced: the part as it is, ``part.operations`` on the tape of its generic
    equations) is not reduced through the Routhian, or None to eliminate its ignorable coordinates ``cyclic``
    (``Scene(reduce=...)``).  A part integrated within the break-even leaves its run with the scene
    (``Scene._keep``), which :meth:`Scene.run` returns."""
    which = ", ".join(cyclic)
    if scene.reduce is False:
        return f"{which} ignorable, not eliminated (reduce=False)"
    if scene.reduce is True:
        return None
    ops = part.operations
    symbolic = REDUCE_SECONDS * ops * len(cyclic) ** 2
    if part.method == "exact":
        return (f"{which} ignorable, not eliminated: the part is linear time-invariant and solved exactly as it is, "
                f"so the Routhian (about {symbolic:.2g} s of symbolic work) would save no integration (reduce=True "
                f"forces it)")
    budget = break_even(len(cyclic))
    with warnings.catch_warnings(record=True) as caught:  # said again when the run is returned (Scene.run)
        warnings.simplefilter("always")
        try:
            res = scene._solve(part, max_evaluations=budget)
        except LagrangianError:
            return None  # at its pace beyond the break-even, or the part as it is does not run: the reduced one may
    scene._keep(part, res, caught)
    return (f"{which} ignorable, not eliminated: the part as it is ran in {res.nfev:.3g} evaluations of {ops} "
            f"operations (about {res.nfev * ops * TAPE_SECONDS:.2g} s), less than the Routhian's about "
            f"{symbolic:.2g} s of symbolic work (break-even {budget:.3g} evaluations; reduce=True forces it)")
