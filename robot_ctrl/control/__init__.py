"""Controller building blocks that join the pipeline stages (feedforward, command assembly)."""
