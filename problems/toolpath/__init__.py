"""Machining toolpaths as tasks: G-code programs (:mod:`.gcode`) and CL data (:mod:`.cl_csv`)."""
