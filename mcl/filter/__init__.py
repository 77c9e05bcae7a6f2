"""The particle filter and its parts: motion and sensor models, numba kernels, resampling,
KLD-sampling, augmented MCL, beam skipping, the likelihood field, the uncertainty of a cloud, the
``lost`` flag and the filter's settings. Imports ``racecar_sim`` (maps, ray caster) only; never the
wrappers or the lab (``mcl.io``, ``mcl.experiments``, ...)."""
