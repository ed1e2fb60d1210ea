"""The cut: the stock a program machines, the material each move removes and where the cutter's
edges are in material (the engagement the cutting-force model needs).  3-axis, program frame, SI."""
