# The ACV image behind docker-compose.yml: web workers, the training worker, a Ray node.
#
#   docker compose build
#
# torch comes from the configured package index; to get its CPU-only build (much smaller),
# pass PyTorch's CPU wheel index: --build-arg PIP_EXTRA_INDEX_URL=<index URL>.
FROM python:3.11-slim-bookworm

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1 \
    MUJOCO_GL=egl \
    ACV_DATA_DIR=/data

# Off-screen MuJoCo rendering: EGL (MUJOCO_GL=egl) and OSMesa (MUJOCO_GL=osmesa), on Mesa.
RUN apt-get update \
 && apt-get install -y --no-install-recommends libegl1 libegl-mesa0 libgl1-mesa-dri libosmesa6 \
 && rm -rf /var/lib/apt/lists/*

WORKDIR /app
ARG TORCH_VERSION=2.13.0
ARG PIP_EXTRA_INDEX_URL=
RUN pip install "torch==${TORCH_VERSION}"

# The package in place (editable): the app finds alembic.ini, migrations/, templates/ and
# static/ next to its code, as in a checkout.
COPY . .
RUN pip install -e ".[ray]"

RUN useradd --create-home --uid 10001 acv \
 && mkdir -p /data \
 && chown acv /data
USER acv
VOLUME ["/data"]
EXPOSE 8000
# Health checks are per service, in docker-compose.yml (the worker serves no HTTP).
CMD ["acv", "serve", "--host", "0.0.0.0", "--port", "8000"]
