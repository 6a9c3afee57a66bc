"""The beam in space: finite differences with ghost nodes, the Richardson pair of grids, and how much of a gap the grid
itself makes (numerical adequacy, grid advice)."""
