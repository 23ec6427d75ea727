"""Motion planners from OMPL: ``ompl:<Planner>`` for each bound geometric planner."""
