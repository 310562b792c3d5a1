"""mpcde: the integration package (scenarios, onboard agent, simulation loop, metrics, CLI)."""

__version__ = "0.1.0"
