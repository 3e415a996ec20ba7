# curvefm: one image for the API (with its web UI) and the workers; docker-compose.yml runs both from it.
# The image installs the same wheel a lab member would: built from the sources and the npm packages that
# package-lock.json pins (three.js, Swagger UI, ReDoc), which the wheel carries (build_vendor.py).

FROM node:20-slim AS npm-packages
WORKDIR /src
COPY package.json package-lock.json ./
RUN npm ci --omit=dev --ignore-scripts --no-audit --no-fund

FROM python:3.11-slim AS wheel
WORKDIR /src
COPY pyproject.toml README.md package.json package-lock.json build_vendor.py ./
COPY curvefm ./curvefm
COPY plugins ./plugins
COPY service ./service
COPY workers ./workers
COPY --from=npm-packages /src/node_modules ./node_modules
RUN pip wheel --no-cache-dir --no-deps --wheel-dir /dist .

FROM python:3.11-slim

# open3d needs libusb at import time and libgomp for its kernels
RUN apt-get update \
    && apt-get install -y --no-install-recommends libusb-1.0-0 libgomp1 \
    && rm -rf /var/lib/apt/lists/*

COPY --from=wheel /dist /dist
RUN wheel=$(ls /dist/curvefm-*.whl) && pip install --no-cache-dir "${wheel}[service]" && rm -rf /dist

RUN useradd --create-home --uid 1000 curvefm && mkdir /data && chown curvefm /data
USER curvefm
WORKDIR /home/curvefm
ENV CURVEFM_DATA=/data
VOLUME /data
EXPOSE 8000

CMD ["python", "-m", "curvefm.service", "--host", "0.0.0.0", "--port", "8000"]
