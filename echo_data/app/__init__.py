"""The production layer: build orchestration, the CLI's dataset commands, episode generation, trials
and the one worker pool they share. It sits above the format library (`echo_data.dataset`), which
imports nothing from here."""
