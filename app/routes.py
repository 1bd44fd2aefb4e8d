"""Every route of the app, mounted by :func:`app.main.create_app`: the REST API under
``/api`` (one router per resource, shown in ``/docs``) and the HTML pages.

The routers live with their feature (``app/<feature>/api.py``, ``pages.py``); this module
only fixes the order in which they are matched.
"""

from __future__ import annotations

from fastapi import APIRouter

from app.evaluations import api as evaluations_api
from app.evaluations import crowd_api as evaluations_crowd_api
from app.evaluations import crowd_pages as evaluations_crowd_pages
from app.evaluations import evaluator_api, researcher_pages, withdraw_pages
from app.evaluations import export_api as evaluations_export_api
from app.evaluations import pages as evaluations_pages
from app.evaluations import practice_api as evaluations_practice_api
from app.evaluations import practice_pages as evaluations_practice_pages
from app.http import auth_pages, errors
from app.labelling import api as labelling_api
from app.labelling import crowd_pages as labelling_crowd_pages
from app.labelling import dataset_api, matches_api, pair_pages, practice_api, practice_pages
from app.labelling import pages as labelling_pages
from app.runs import (
    advisors_api,
    agents_api,
    checkpoint_api,
    clip_api,
    compare_pages,
    experiment_pages,
    experiments_api,
)
from app.runs import api as runs_api
from app.runs import pages as runs_pages
from app.studies import api as studies_api
from app.studies import crowd_api as studies_crowd_api
from app.studies import dashboard_api as studies_dashboard_api
from app.studies import downloads
from app.studies import gold_api as studies_gold_api
from app.studies import gold_pages as studies_gold_pages
from app.studies import pages as studies_pages
from app.surveys import api as surveys_api
from app.surveys import crowd_api as surveys_crowd_api
from app.surveys import crowd_pages as surveys_crowd_pages
from app.surveys import pages as surveys_pages
from app.webhooks import api as webhooks_api
from app.webhooks import pages as webhooks_pages

api_router = APIRouter(prefix="/api", responses=errors.RESPONSES)
for _router in (
    studies_api.router,
    labelling_api.router,
    dataset_api.router,
    practice_api.router,
    matches_api.router,
    runs_api.router,
    checkpoint_api.router,
    clip_api.router,
    advisors_api.router,
    agents_api.router,
    experiments_api.router,
    surveys_api.router,
    studies_crowd_api.link_router,
    studies_crowd_api.router,
    studies_gold_api.router,
    studies_dashboard_api.router,
    surveys_crowd_api.router,
    webhooks_api.router,
    evaluations_api.router,
    evaluations_practice_api.router,
    evaluator_api.router,
    evaluations_crowd_api.router,
    evaluations_export_api.router,
):
    api_router.include_router(_router)

pages_router = APIRouter()
for _pages in (
    auth_pages,
    labelling_pages,
    practice_pages,
    pair_pages,
    downloads,
    studies_pages,
    runs_pages,
    compare_pages,
    experiment_pages,
    surveys_pages,
    labelling_crowd_pages,
    studies_gold_pages,
    surveys_crowd_pages,
    webhooks_pages,
    evaluations_pages,
    evaluations_practice_pages,
    researcher_pages,
    evaluations_crowd_pages,
    withdraw_pages,
):
    pages_router.include_router(_pages.router)
