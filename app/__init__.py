"""ACV application layer: web app, services, jobs and the ``acv`` command line."""
