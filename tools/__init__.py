"""Developer tools (``python -m tools``, ``./dev.sh build|samples|bench|mutants``): the
extension build, the sample scenes, the benchmarks, mutation testing. Neither the
extension nor the users' commands (``python -m headless``) import them."""
