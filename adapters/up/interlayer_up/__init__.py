"""Task planners through Unified-Planning: any installed OneshotPlanner engine by name."""
