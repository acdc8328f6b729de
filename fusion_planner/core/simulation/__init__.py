"""Closed-loop simulation: the world, scenarios, and episodes and batches of runs."""
