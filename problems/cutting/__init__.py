"""Metal-cutting tasks: measured cutting forces, the identification of cutting coefficients."""
