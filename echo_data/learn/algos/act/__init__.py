"""ACT-style action chunking: a small transformer, chunk size k, temporal ensembling when acting."""
