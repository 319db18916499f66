"""The bundled recipes (TOML package data), so that ``mirrorlab demo`` finds its recipe from any folder.

``mirrorlab run sessions/<recipe>.toml`` reads the same files in a checkout; see ``README.md`` here.
"""
