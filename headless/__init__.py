"""AutoSCOOP without a user interface: ``python -m headless SUBCOMMAND``.

Also runs inside a Blender binary:
``blender --background SCENE.blend --python headless/__main__.py -- SUBCOMMAND ...``.
"""
