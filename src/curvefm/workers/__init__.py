"""Job functions and the job queue: RQ on Redis, or an in-process executor when no Redis is configured."""
