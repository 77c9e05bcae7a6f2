"""The car: its models ([`racecar_sim.car.models`][racecar_sim.car.models]), its pymunk body and
physics among the map's walls, its free steps in numba, its state, its clock and lidar schedule, and
random start poses from a table shared per map. Imports the maps and the settings; never the sensors,
the world or an env (N cars on arrays are [`racecar_sim.fleet`][racecar_sim.fleet])."""
