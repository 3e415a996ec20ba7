# curvefm: one image for the API (with its web UI) and the workers; docker-compose.yml runs both from it.

# three.js for the web UI, at the version package-lock.json pins (the UI has no build step)
FROM node:20-slim AS ui-vendor
WORKDIR /ui
COPY package.json package-lock.json ./
RUN npm ci --omit=dev --no-audit --no-fund

FROM python:3.11-slim

# open3d needs libusb at import time and libgomp for its kernels
RUN apt-get update \
    && apt-get install -y --no-install-recommends libusb-1.0-0 libgomp1 \
    && rm -rf /var/lib/apt/lists/*

WORKDIR /app
COPY pyproject.toml README.md ./
COPY curvefm ./curvefm
COPY plugins ./plugins
COPY service ./service
COPY workers ./workers
RUN pip install --no-cache-dir ".[service]"
COPY --from=ui-vendor /ui/node_modules/three /opt/three

RUN useradd --create-home --uid 1000 curvefm && mkdir /data && chown curvefm /data
USER curvefm
ENV CURVEFM_DATA=/data CURVEFM_THREE_DIR=/opt/three
VOLUME /data
EXPOSE 8000

CMD ["python", "-m", "curvefm.service", "--host", "0.0.0.0", "--port", "8000"]
