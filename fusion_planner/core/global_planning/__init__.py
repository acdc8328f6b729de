"""Global planning on a grid: neighbourhoods, the search engine, refinement, metrics, the planner.

Also the obstacle layer, which marks what a range sensor saw into the planner's grid.
"""
