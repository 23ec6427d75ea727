"""interlayer_pr2: the PR2 pick-and-place domain (Fig. 3 of Srivastava et al., ICRA 2014) on Pinocchio + Coal."""
