# curvefm: one image for the API (with its web UI) and the workers; docker-compose.yml runs both from it.
# The image installs the same wheel a lab member would: built from the sources and the npm packages that
# package-lock.json pins (three.js, Swagger UI, ReDoc), which the wheel carries (build_vendor.py), with the
# service, cholmod and postgresql extras. Its eigensolver factors with CHOLMOD (SuiteSparse), as a checkout does.
#
# The base images are build arguments, so that the image builds where no registry of images is reachable
# (scripts/test-deploy.sh builds it from a Debian 12 made by debootstrap): Python is Debian's python3 (3.11) in a
# virtual environment, not python:3.11-slim, because a stock Debian root file system is all such a build needs.
ARG BASE_IMAGE=debian:bookworm-slim
ARG NODE_IMAGE=node:20-bookworm-slim

FROM ${NODE_IMAGE} AS npm-packages
WORKDIR /src
COPY package.json package-lock.json ./
RUN npm ci --omit=dev --ignore-scripts --no-audit --no-fund

FROM ${BASE_IMAGE} AS python
RUN apt-get update \
    && apt-get install -y --no-install-recommends python3 python3-venv \
    && rm -rf /var/lib/apt/lists/* \
    && python3 -m venv /opt/curvefm
ENV PATH=/opt/curvefm/bin:$PATH

# The source tree as .dockerignore lets it through (no list of folders here: a new package under src/curvefm
# reaches the image by itself); tests/deploy/test_image_sources.py builds a wheel from exactly these COPY lines.
FROM python AS wheel
WORKDIR /src
COPY . .
COPY --from=npm-packages /src/node_modules ./node_modules
RUN pip wheel --no-cache-dir --no-deps --wheel-dir /dist .

# The wheel and its extras installed into the virtual environment; scikit-sparse (the cholmod extra) compiles here
# against SuiteSparse's headers, so the compilers stay out of the runtime image.
FROM python AS install
RUN apt-get update \
    && apt-get install -y --no-install-recommends build-essential python3-dev libsuitesparse-dev \
    && rm -rf /var/lib/apt/lists/*
COPY --from=wheel /dist /dist
RUN wheel=$(ls /dist/curvefm-*.whl) && pip install --no-cache-dir "${wheel}[service,cholmod,postgresql]"

FROM python
# CHOLMOD's library for scikit-sparse; open3d-cpu 0.20 loads libusb, libgomp, libGL and libEGL at import time
# (scripts/setup.sh installs the same)
RUN apt-get update \
    && apt-get install -y --no-install-recommends libcholmod3 libusb-1.0-0 libgomp1 libgl1 libegl1 \
    && rm -rf /var/lib/apt/lists/*
COPY --from=install /opt/curvefm /opt/curvefm

RUN useradd --create-home --uid 1000 curvefm && mkdir /data && chown curvefm /data
USER curvefm
WORKDIR /home/curvefm
ENV CURVEFM_DATA=/data
VOLUME /data
EXPOSE 8000

CMD ["python", "-m", "curvefm.service", "--host", "0.0.0.0", "--port", "8000"]
