"""The bundled models' generator, one module per job (``tools/make_models.py`` runs it).

``params`` holds every number; ``patches`` parametrises the open surfaces z = g(x, y) and
``patch_mesh`` meshes them (with ``relax`` and ``connectivity``); ``solids`` meshes the
closed shapes; ``distances`` measures points against the analytic surfaces; ``catalogue``
lists the models; ``export`` writes and checks one; ``measure`` and ``readme`` make the
table of ``models/README.md``. Imported as the top-level package ``shapes`` (``tools/`` is
the script's folder, first on ``sys.path``).
"""
