"""Built-in plugins of lagrangian, registered through the entry-point group
``lagrangian`` exactly like third-party plugins.

- :mod:`lagrangian.plugins.mechanics`: the ``mechanical`` domain (node
  positions in 1, 2 or 3 dimensions) and its point mass, spring, damper,
  uniform gravity, applied force and prescribed motion.
- :mod:`lagrangian.plugins.circuits`: the ``electrical`` domain (loop
  charges or node flux linkages) and its inductor, capacitor, resistor,
  voltage source and current source.
"""
