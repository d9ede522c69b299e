"""The collision layer: the robot's and the scene's bodies, collision checks of states and
sampled motions, and motions proven free between samples.

- Bodies: ``bodies`` (the robot's geometry, built once per description), ``assembly``
  (a world's bodies: links, carried objects, obstacles, and the pairs worth checking),
  ``table`` (the body table the kernels read).
- Bounds: ``obbtree`` (OBB trees, the broad phase), ``hulls`` (convex hulls), ``gjk``
  (GJK in numba), ``parts`` (part hulls of concave meshes), ``advance`` (conservative
  advancement: a pair proven free over a stretch of states), ``body_speed`` (how fast a
  body moves where it is now).
- The world: ``world`` (:class:`~.world.CollisionWorld`: state checks, sweeps, a pair's
  distance by kind), ``compiled`` (calling numba kernels past the dispatcher).
- Point clouds: ``cloud_body`` (a cloud's cells as one body: a tree of cell boxes),
  ``cloud_keep`` (a cloud posed, self-filtered and kept, with its unknown space).
- Allowed pairs: ``acm`` (the allowed-collision matrix), ``acm_gen`` (computing it as
  MoveIt's setup assistant does), ``acm_proof`` (pairs proven never to collide).
- Proofs: ``certify`` (the certifier: the proof's outline and its compiled walk),
  ``ladder`` (the near-contact ladder: trees, hulls, part hulls or exact distances),
  ``resume`` (the walk's protocol with Python), ``one_dim`` (pairs one joint moves,
  proven over cells), ``certificate`` (a motion's certificate and its rung counts),
  ``motion_check`` (straight motions checked at samples, and OMPL's checkers).
"""
