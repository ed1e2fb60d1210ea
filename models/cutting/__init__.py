"""Metal cutting: the end mill's geometry (:mod:`.cutter`), the material's mechanistic cutting
coefficients (:mod:`.material`) and the cutting force of an engaged end mill (:mod:`.force`).

Units SI (m, rad, N, N·m); frames are stated per function.
"""
