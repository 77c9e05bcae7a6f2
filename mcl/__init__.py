"""mcl: Monte Carlo Localization (particle filter) for racecar_sim."""

__version__ = "0.1.0"
