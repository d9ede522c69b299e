"""The collision layer: the collision world, and motions proven free between samples.

- ``world``: :class:`~arduinobot.planner.collision.world.CollisionWorld` (python-fcl):
  the robot's links, what it carries and the scene.
- ``table``: the body table (every body, its kind and pose, the checked pairs);
  ``assembly``: a world's bodies assembled in its order; ``bodies``: the robot's
  geometry built once per description.
- ``obbtree``: OBB trees, a conservative broad phase in numba; ``hulls``: convex hulls;
  ``parts``: part hulls of concave meshes; ``gjk``: GJK on convex vertex sets.
- ``acm``: the allowed-collision matrix; ``acm_gen``: computed as MoveIt's setup
  assistant does, made sound; ``acm_proof``: pairs that never collide within the limits.
- ``certify``: the certifier of continuous motions; ``certificate``: its verdict and
  clearance; ``advance``: conservative advancement; ``body_speed``: motion bounds;
  ``one_dim``: pairs whose relative motion is one-dimensional; ``resume``: the protocol
  between the compiled walk and its Python side; ``compiled``: calling a numba kernel's
  compiled variant directly.
- ``motion_check``: straight joint-space motions checked, OMPL's checkers on it.
"""
