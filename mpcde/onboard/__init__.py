"""What runs on each drone: the agent interface, the factory, one module per stack, perception glue.

Onboard code sees only what a drone would: its camera frames (and its own
detector's boxes on them), its own pose estimate and its radio inbox; never
ground truth (tests/unit/test_import_rules.py holds the imports to this).
"""
