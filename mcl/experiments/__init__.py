"""The experiment harness: one drive (``runs``), scenarios, executors (``runner``, ``ray_executor``),
the odometry-noise sweep, the recovery experiments and the replay of recorded bags through the filter.

Built on the filter library; the library never imports this package.
"""
