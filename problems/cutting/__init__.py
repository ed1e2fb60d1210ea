"""The cut as the load: the stock and what a program removes from it, the engagement of the cutter
at every sample, and the cutting wrench along the program (``docs/cutting.md``)."""
