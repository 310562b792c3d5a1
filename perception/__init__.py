"""perception: onboard sensing (detector, back-projection, map, tracks).

Imports :mod:`sim.types` only. Sees camera frames without segmentation, the
drone's own pose estimate, never another drone's ground truth.
"""
