"""The HTTP service: FastAPI app, sessions held in-process, heavy work sent to the job queue."""
