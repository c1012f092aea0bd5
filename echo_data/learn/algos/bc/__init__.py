"""BC (MLP): behaviour cloning with an MLP head and optional open-loop action chunks."""
