"""Cost terms of eq. (9): collision (probability + kinetic term), COLREGS, grounding, path."""
