"""The human curator in a browser: ``amaze-curate`` runs an EDHuCAT session whose curator is a page.

* :mod:`experiments.curate.cli`: the command (options, the token, the server);
* :mod:`experiments.curate.session`: the curriculum loop in a worker thread and
  the state the page shows, with the curator that waits for the page's answers;
* :mod:`experiments.curate.server`: the FastAPI application (routes, token,
  CSRF, request limits);
* :mod:`experiments.curate.design`: maze strings to form fields and back, and
  what the page shows of a maze;
* ``templates/`` and ``static/``: the page (plain HTML, CSS and JavaScript).

It lives in ``experiments`` because a session runs either trainer (RL or
evolution), which only the top layer may import.
"""
