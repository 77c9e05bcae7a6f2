"""The simulator's settings: `EnvConfig` ([`racecar_sim.settings.config`][racecar_sim.settings.config]),
the physical bounds of every number, validation written once, and building dataclasses from
mappings or YAML files. Imports the maps and the settings classes of the sensors and the world."""
