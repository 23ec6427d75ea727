"""A Franka Panda takes a box out of a shelf past a blocker: a scene for the manipulation layer."""
