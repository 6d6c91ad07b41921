"""Kinematic synthesis (pipeline step 1): learned movement primitives (anechoic mixtures)."""
