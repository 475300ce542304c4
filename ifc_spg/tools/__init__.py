"""Command-line tools: ``ifc-spg`` and its verbs, benchmarks, demo."""
