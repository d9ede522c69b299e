"""The proof that a motion is free between its samples.

- ``certify``: the certifier, the proof's outline and its compiled walk.
- ``nearness``: the order the walk takes the pairs in, nearest first.
- ``ladder``: the near-contact ladder (trees, hulls, part hulls, exact distances).
- ``certificate``: a motion's certificate, its clearance and rung counts.
- ``resume``: the protocol between the compiled walk and its Python side.
- ``advance``: conservative advancement, a pair proven free over a stretch of states.
- ``one_dim``: pairs one joint moves, proven over cells.
- ``body_speed``: how fast a body moves where it is now.
- ``motion_check``: straight motions checked at samples, and OMPL's checkers on them.
"""
