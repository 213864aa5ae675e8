"""One Lagrangian from the component graph (:mod:`.assembly`) and its equations of motion (:mod:`.derive`,
:mod:`.equations`).
"""
