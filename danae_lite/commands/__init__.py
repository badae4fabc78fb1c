"""The command line's subcommands, one module each (:mod:`~danae_lite.commands.reproduce`,
:mod:`~danae_lite.commands.leaderboard`), what they share (:mod:`~danae_lite.commands.prepare`) and the
data flags (:mod:`~danae_lite.commands.data_flags`). :mod:`danae_lite.cli` parses the arguments and
imports the one command it runs."""
