"""Rendering the drones' cameras: the analytic renderer (default), TinyRenderer, and the pool of worker processes.

A render becomes the frame a drone receives in :mod:`sim.rendering.camera_rig`
(the depth sensor model and the drone's own pose estimate).
"""
