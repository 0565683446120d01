"""One module per paper's experiments; each defines ``experiments()`` for the registry."""
