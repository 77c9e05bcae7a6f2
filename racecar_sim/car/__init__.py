"""The car's own parts that envs share: its clock and lidar schedule
([`racecar_sim.car.clock`][racecar_sim.car.clock])."""
