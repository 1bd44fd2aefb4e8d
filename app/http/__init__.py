"""The HTTP layer every feature's routes share: dependencies (``SessionDep``, callers),
error handlers, CSRF, page rendering, guards, cookies, rate limits and researcher login.

It knows no feature: a feature's ``api.py`` and ``pages.py`` import it, never the reverse.
"""
