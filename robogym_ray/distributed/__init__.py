"""The only place Ray actors are defined: the ``ray.remote`` wrappers of the plain classes in
``experience/``, ``supervision/``, ``realrobot/`` and ``learner/``, the server provider that
leases supervised servers, and the ``manager`` command."""
