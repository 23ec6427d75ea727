"""Motion planners and timing beyond sampling: ``ik:cartesian`` (differential IK along straight
end-effector lines), ``trajopt`` (sequential convex optimisation, proxsuite) and TOPP-RA timing."""
