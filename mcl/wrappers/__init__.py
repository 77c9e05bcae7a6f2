"""The filter inside the envs: [`LocalizationWrapper`][mcl.wrappers.single.LocalizationWrapper] (one
car), [`LocalizedVectorEnv`][mcl.wrappers.vector.LocalizedVectorEnv] (a vector env),
[`LocalizedRaceEnv`][mcl.wrappers.race.LocalizedRaceEnv] (a race), the localization settings they
share, their checks and the per-step error log. Imports the envs and ``mcl.filter``; the live view
and recorders attach through the wrappers' ``on_step`` hook."""
