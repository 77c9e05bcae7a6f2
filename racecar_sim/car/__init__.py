"""The car: its models ([`racecar_sim.car.models`][racecar_sim.car.models]), its pymunk body and
physics among the map's walls, its free steps in numba, its clock and lidar schedule, the fleet of
N cars' shared tables and random start poses. Imports the maps and the settings; never the sensors,
the world's obstacles or an env."""
