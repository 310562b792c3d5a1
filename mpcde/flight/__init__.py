"""Flying a scenario: the event loop, flight metrics, the run folder, plots and video."""
