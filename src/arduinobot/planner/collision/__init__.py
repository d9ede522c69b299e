"""The collision layer: the robot's and the scene's bodies, collision checks of states and
sampled motions, and motions proven free between samples.

- Bodies: ``bodies`` (the robot's geometry, built once per description), ``assembly``
  (a world's bodies: links, carried objects, obstacles, and the pairs worth checking),
  ``table`` (the body table the kernels read).
- The world: ``world`` (:class:`~.world.CollisionWorld`: state checks, sweeps, a pair's
  distance by kind), ``compiled`` (calling numba kernels past the dispatcher).
- Point clouds: ``cloud_body`` (a cloud's cells as one body: a tree of cell boxes),
  ``cloud_tree`` (that tree's build, split by the surface-area heuristic),
  ``cloud_tiles`` (its boundary's FCL BVHs in tiles, each built on first use),
  ``cloud_keep`` (a cloud posed, self-filtered and kept, with its unknown space).
- Allowed pairs: ``acm`` (the allowed-collision matrix), ``acm_gen`` (computing it as
  MoveIt's setup assistant does), ``acm_proof`` (pairs proven never to collide).
- ``bounds/``: conservative distance bounds, cheapest first (OBB trees, hulls, GJK,
  part hulls).
- ``proof/``: the proof that a motion is free between samples (the certifier, its
  near-contact ladder, conservative advancement, one-joint cells, the certificate).
"""
