"""The subcommands, a module each: ``model`` (check, info, urdf, limits), ``serve``,
``srdf``, ``view``, ``plan`` (plan, fk, ik), ``state`` (check-state), ``execute``,
``scene`` (with ``scene_see``: ``scene see IMAGE``) and ``task``. Each has
``add_parsers(sub)``."""
