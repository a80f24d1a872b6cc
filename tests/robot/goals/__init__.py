"""Goals: the goal rule and machine, goto and goto_point, every ending, progress, stale links."""
