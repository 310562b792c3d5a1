"""Rendering the drones' cameras: the analytic renderer (default), TinyRenderer, and the pool of worker processes."""
