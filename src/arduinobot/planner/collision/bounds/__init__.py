"""Conservative bounds on distances between bodies, cheapest first.

- ``obbtree``: OBB trees of the bodies, the broad phase (numba).
- ``hulls``: convex hulls and their distance bounds.
- ``gjk``: GJK on convex vertex sets (numba).
- ``parts``: part hulls of concave CAD meshes, a tight bound where the hulls touch.
"""
