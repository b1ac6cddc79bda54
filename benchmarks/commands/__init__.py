"""One module per `msvdd-bench` subcommand; each exposes `COMMAND: benchmarks.command.Command`."""
