"""The filter inside the envs: [`LocalizationWrapper`][mcl.wrappers.single.LocalizationWrapper] (one
car), [`LocalizedVectorEnv`][mcl.wrappers.vector.LocalizedVectorEnv] (a vector env),
[`LocalizedRaceEnv`][mcl.wrappers.race.LocalizedRaceEnv] (a race), the localization settings they
share, their checks, the per-step error log and the step hooks
([`mcl.wrappers.hooks`][mcl.wrappers.hooks]). Imports the envs and ``mcl.filter``, never ``mcl.io``:
the bag recorder and the live view attach to
[`LocalizationWrapper`][mcl.wrappers.single.LocalizationWrapper] as step hooks."""
