"""The paper's two-level agent: a planner that answers with a skill chain, skill policies that act.

`runtime.run_episode` runs one episode with them in `echo_data.envs.EchoDataEnv`; `builtin` holds
the oracle (scripted experts), random and still policies and the oracle planner; `loading` finds
an agent by name, `module:Class` or checkpoint folder.
"""
