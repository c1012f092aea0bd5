"""BC-RNN: a GRU over the steps of a skill, its state reset at each skill's start."""
