"""The dataset format library: on-disk layout, encoding, shards, writer, validation, statistics and
exports. It imports nothing from the layers above it (the application in `echo_data.app`, the
environment, agents, evaluation); tests/test_layering.py checks that."""
