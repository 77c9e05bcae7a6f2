"""The ``racecar-sim`` console command: one module per subcommand, each with ``main(argv)``."""
