"""interlayer_manip: the manipulation layer on Pinocchio + Coal (world state, collision sync, motion
queries, IK and grasps, pick / place / move refinement, timing, the validator and the drawing), shared by
the manipulation domains (pr2, clutter, drawer, dinner, pbjson)."""
