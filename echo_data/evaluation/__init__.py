"""`echo-data evaluate`: the paper's metrics for a policy run closed-loop in `echo_data.envs`."""
