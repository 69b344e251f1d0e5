"""Pointwise constitutive laws: pure functions on arrays, no knowledge of elements."""
