"""The settings that the workers and the API share: where the queue is, and how jobs are sized. Read from
``CURVEFM_<NAME>`` variables.

The API's :class:`curvefm.service.settings.Settings` extends :class:`QueueSettings`; ``curvefm worker`` reads it alone.
A setting is a typed field with a description (the documentation shows it). Its variable is ``CURVEFM_`` and its
name in capitals, less the unit of a duration in seconds (``job_ttl_s``: ``CURVEFM_JOB_TTL``), unless the field
names another as its ``validation_alias``.
"""

from __future__ import annotations

from typing import Annotated

from pydantic import AliasGenerator, BeforeValidator, Field
from pydantic_settings import BaseSettings, SettingsConfigDict

from curvefm.workers.sizing import JobSizing, available_memory, parse_bytes

ENV_PREFIX = "CURVEFM_"


def variable(field: str) -> str:
    """The environment variable of the field named ``field``: ``job_ttl_s`` -> ``CURVEFM_JOB_TTL``."""
    return ENV_PREFIX + field.removesuffix("_s").upper()


class QueueSettings(BaseSettings):
    model_config = SettingsConfigDict(
        alias_generator=AliasGenerator(validation_alias=variable),
        env_ignore_empty=True,  # an empty variable (docker-compose's ``${X:-}``) means its default
        populate_by_name=True,  # a field's validation_alias is its variable; the code sets it by name
        frozen=True,
        extra="forbid",
    )

    redis_url: str | None = Field(
        None, description="Redis for the job queue (RQ), e.g. redis://:PASSWORD@host:6379/0; none: jobs run in-process"
    )
    database_url: str | None = Field(
        None, description="The records' database, e.g. postgresql+psycopg://user@host/curvefm; none: <data>/curvefm.db"
    )
    queue_prefix: str = Field(
        "", description="Prefix of the queue names, so that several deployments (or test runs) can share one Redis"
    )
    job_timeout_floor_s: float = Field(
        900.0,
        gt=0,
        allow_inf_nan=False,
        description="The shortest time limit of a job, in seconds, however small its meshes",
    )
    job_timeout_factor: float = Field(
        20.0,
        gt=0,
        allow_inf_nan=False,
        description="A job's time limit: this many times its run time on a quiet machine, estimated from its meshes' "
        "vertices and k (docs/operations.md, 'Job sizes')",
    )
    job_memory_margin: float = Field(
        1.25,
        ge=1.0,
        allow_inf_nan=False,
        description="A job's stated peak memory: this many times the fit of the measured peaks",
    )
    worker_memory: Annotated[int | None, BeforeValidator(parse_bytes)] = Field(
        None,
        gt=0,
        description="The memory a worker (or the API's in-process executor) may give a job, e.g. 8G; larger jobs "
        "are refused as too_large. None: the memory available when it starts (the machine's, or its cgroup's)",
    )

    @property
    def sizing(self) -> JobSizing:
        return JobSizing(self.job_timeout_floor_s, self.job_timeout_factor, self.job_memory_margin)

    def memory_budget(self) -> int:
        """The worker's budget: :attr:`worker_memory`, or the memory available now."""
        return self.worker_memory if self.worker_memory is not None else available_memory()
