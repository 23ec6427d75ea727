"""The paper's running example (Fig. 2): a planar gripper, blocks in a dead-end corridor."""
