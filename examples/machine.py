"""The machine the README's command lines run: an isolated mass on a moving base, and a mass on its own spring.

``build()`` returns the model:

- ``m1`` (0.3 kg at node ``p``) on a spring ``k1`` (4 N/m) and a damper
  ``c1`` (0.05 N s/m) to the base ``b``, whose position is prescribed
  (``base``: still at 0 unless driven; the input of ``lagrangian ac``);
- ``solo`` (1 kg at node ``s``) on a spring ``ks`` (1 N/m) to the ground:
  a part of the model no output of the isolator needs (a scene drops it).

From the shell (in the project's directory)::

    lagrangian scene examples/machine.py:build -o x_s -o "T[solo]" --t-end 5 --initial x_s=1 --csv out.csv
    lagrangian ac examples/machine.py:build --input base -o x_p --start 0.1 --stop 10
    lagrangian sweep examples/machine.py:build --param k_k1=1:10:50 --param c_c1=log:1e-3:1:20 -o x_p --out sweep.nc
"""

import lagrangian as lg


def build() -> lg.Model:
    m = lg.Model("machine")
    m.add("prescribed_motion", "base", "b", position=0)
    m.add("mass", "m1", "p", m=0.3)
    m.add("spring", "k1", ("b", "p"), k=4.0)
    m.add("damper", "c1", ("b", "p"), c=0.05)
    m.add("mass", "solo", "s", m=1.0)
    m.add("spring", "ks", ("ground", "s"), k=1.0)
    return m
