"""Rigid-body collision scenes on Coal: named boxes and cylinders, a moving body, which objects it hits."""
