"""Independent references of the tests and the report (they need SciPy; they are
not part of the installed package):

* ``reference``: the discrete quaternion model in NumPy, solved on its own.
* ``shooting``: a tight-tolerance shooting solution of the continuous Kirchhoff rod.
* ``shooting_held``: the same with a pinned or clamped tip.
"""
