"""mirrorlab: the top-level package, installed as ``mirrorlab/__init__.py`` (``package-dir`` in pyproject.toml).

It holds no code. It exists because a regular package wins over a namespace portion: were
``mirrorlab`` a namespace package, ``python`` started beside a clone folder named ``mirrorlab`` (the
README's layout, ``shared/`` next to the clone) would import that clone's ``core/`` through the
current directory instead of the installed package.
"""
