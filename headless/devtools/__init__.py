"""Developer tools behind ``python -m headless build|samples|bench``: the extension
build, the sample scenes and the benchmarks. Users' commands (``coverage``,
``optimize``) never import them."""
