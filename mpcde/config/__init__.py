"""Scenario configuration: the sections of a scenario file, their checks, YAML I/O and the mode names.

Reading a scenario imports only configuration (each stack's settings live in
their own module here), never a planner or a simulator.
"""
