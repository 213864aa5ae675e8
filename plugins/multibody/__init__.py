"""Built-in plugin: rigid bodies and joints, in the plane (``dim=2``) and in space (``dim=3``).

Bodies are nodes of the mechanical domain; joints are branches between two
bodies (``ground`` is the fixed frame).  The joints of a spanning tree rooted
at ground give every body its pose — rotation ``R`` and origin ``p`` — as
functions of the joint coordinates (or of time, for a driven joint); every
other joint closes a kinematic loop and becomes a holonomic constraint kept
with a Lagrange multiplier.  Points of a body are nodes named
``"<body>.<point>"`` (``"<body>.com"`` and ``"<body>.origin"`` always exist),
so springs, dampers, forces and point masses of the mechanics plugin attach
to them unchanged.

Conventions.  A joint ``(parent, child)`` sits at ``parent_point`` (in the
parent's frame) and ``child_point`` (in the child's frame), which coincide.
Planar: a revolute joint's angle ``θ`` turns the child by ``θ`` relative to
the parent (``absolute=True``: ``θ`` is the child's angle to the fixed x
axis); a prismatic joint slides the child by ``s`` along ``axis`` (parent
frame).  Spatial: revolute about ``axis`` (parent frame); spherical and free
joints use three body-fixed angles in the ``sequence`` given (default ``"xyz"``:
``alpha``, ``beta``, ``gamma``, singular at ``beta = ±π/2``; another Tait–Bryan
sequence names each angle after its axis, alpha about x, beta about y, gamma
about z: ``"zyx"`` gives ``gamma``, ``beta``, ``alpha``; a proper Euler
sequence such as ``"zxz"``: ``phi``, ``theta``, ``psi``, singular at
``theta = 0`` or ``π``) — see :class:`Spherical`.

The plugin's modules: :mod:`.rotations` (poses, rotation matrices, the angle
sequences), :mod:`.checks` (parameter checks they share), :mod:`.bodies`,
:mod:`.joints`, :mod:`.loads` (torques, rotational springs and dampers on
bodies, a knife edge), :mod:`.rolling` (rolling without slipping on the ground), :mod:`.kinematics` (poses from the joint tree, loop closures),
:mod:`.constraints` (consistent initial conditions) and :mod:`.hooks` (the
hook implementation); this package re-exports their public names.

>>> import lagrangian as lg, sympy as sp
>>> m = lg.Model("pendulum", dim=2)
>>> _ = m.add("rod", "arm", "arm", m=1, length=2)
>>> _ = m.add("revolute", "pin", ("ground", "arm"), absolute=True)
>>> _ = m.add("gravity", "g", g=9.81, direction=(0, -1))
>>> m.coordinate_names
['theta_pin']
>>> sp.trigsimp(m.mass_matrix)  # m L²/3 about the pin
Matrix([[4/3]])
"""

# the public names of the modules, all importable from here as before the split (some outside __all__)
from .bodies import Body, Disc, Link, Rod
from .checks import lg_param_error  # noqa: F401
from .constraints import (
    ConsistentStart,
    CoordinatePartition,
    consistent_initial,
    constraint_residual,
    independent_coordinates,
)
from .hooks import register_component_types  # noqa: F401 - pluggy registers this module: the hook must be here
from .joints import Fixed, Free, PlanarJoint, Prismatic, Revolute, Spherical
from .kinematics import build_kinematics  # noqa: F401 - the mechanics plugin's domain calls it
from .loads import BodyTorque, RotationalDamper, RotationalSpring  # noqa: F401
from .rolling import Rolling
from .rotations import PROPER_EULER, SEQUENCES, TAIT_BRYAN, Pose, transform  # noqa: F401

__all__ = [
    "Pose", "Body", "Link", "Rod", "Disc", "Revolute", "Prismatic", "Spherical", "PlanarJoint", "Fixed", "Free", "Rolling",
    "CoordinatePartition", "ConsistentStart", "independent_coordinates", "consistent_initial", "constraint_residual",
]

# doctest.testmod(lagrangian.plugins.multibody) finds the examples of what a module defines; those of the names
# re-exported here run with this module's through __test__.
__test__ = {name: globals()[name] for name in __all__}
