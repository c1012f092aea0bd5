"""Reference learners trained on echo-data: behaviour cloning per skill and an audio planner.

`features` turns dataset observations into model inputs (the one preprocessing path shared by
training and acting), `models` holds the networks, `bc` / `planner` the training loops and the
loadable policies, `runs` the run-folder files. torch is imported only by modules that need it.
"""
