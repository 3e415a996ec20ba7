"""The service settings (``curvefm.service.settings``): ``CURVEFM_*`` variables, ``serve`` options over them, and
an error naming the variable or option of a bad value. No server: the settings model alone."""

from __future__ import annotations

import pytest

from curvefm.errors import InvalidInput
from curvefm.service.settings import LIMITS, LOOPBACK_NAMES, Settings, env_name


@pytest.fixture(autouse=True)
def clean_environment(monkeypatch):
    for name in Settings.model_fields:
        monkeypatch.delenv(env_name(name), raising=False)


def test_variables_set_settings_and_options_win(monkeypatch, tmp_path):
    monkeypatch.setenv("CURVEFM_MAX_K", "50")
    monkeypatch.setenv("CURVEFM_JOB_TTL", "60")  # a variable not named after its field (job_ttl_s)
    monkeypatch.setenv("CURVEFM_ALLOWED_HOSTS", "A.example., [::1]")
    monkeypatch.setenv("CURVEFM_DATA", str(tmp_path))
    monkeypatch.setenv("CURVEFM_RATE_LIMIT", "")  # empty: the default
    settings = Settings.from_env(max_k=5, quota_jobs=None)
    assert settings.max_k == 5 and settings.session_limits.max_k == 5
    assert settings.job_ttl_s == 60.0 and settings.data_dir == tmp_path
    assert settings.allowed_hosts == ("a.example", "::1")
    assert settings.rate_limit == Settings.model_fields["rate_limit"].default
    assert settings.quota_jobs == Settings.model_fields["quota_jobs"].default


def test_the_bound_address_chooses_the_default_hosts_unless_they_are_set(monkeypatch):
    assert Settings.from_env().allowed_hosts == LOOPBACK_NAMES
    assert "192.0.2.7" in Settings.from_env(bind_host="192.0.2.7").allowed_hosts
    monkeypatch.setenv("CURVEFM_ALLOWED_HOSTS", "*")
    assert Settings.from_env(bind_host="192.0.2.7").allowed_hosts == ("*",)


@pytest.mark.parametrize(
    ("variable", "value"),
    [
        ("CURVEFM_MAX_K", "0"),
        ("CURVEFM_MAX_UPLOAD_BYTES", "many"),
        ("CURVEFM_QUOTA_BYTES", "-1"),
        ("CURVEFM_SESSION_LOCK_TIMEOUT", "nan"),
        ("CURVEFM_GIL_SWITCH_MS", "inf"),
        ("CURVEFM_ALLOWED_HOSTS", " , "),
        ("CURVEFM_JOB_TIMEOUT_FACTOR", "inf"),
        ("CURVEFM_JOB_MEMORY_MARGIN", "0.5"),
        ("CURVEFM_WORKER_MEMORY", "lots"),
    ],
)
def test_a_bad_variable_is_an_error_naming_it(monkeypatch, variable, value):
    monkeypatch.setenv(variable, value)
    with pytest.raises(InvalidInput, match=f"{variable}={value!r} is not valid"):
        Settings.from_env()


def test_a_bad_option_is_an_error_naming_it():
    with pytest.raises(InvalidInput, match="--max-k=-3 is not valid.*--job-ttl=-1.0 is not valid"):
        Settings.from_env(max_k=-3, job_ttl_s=-1.0)
    with pytest.raises(TypeError, match="unknown settings: max_q"):
        Settings.from_env(max_q=1)


def test_every_setting_has_a_description_and_every_limit_a_field():
    assert all(field.description for field in Settings.model_fields.values())
    assert set(LIMITS) <= set(Settings.model_fields)


def test_single_sign_on_needs_its_three_settings_and_never_shows_the_secret(monkeypatch):
    assert not Settings.from_env().sso
    monkeypatch.setenv("CURVEFM_OIDC_ISSUER", "https://login.uni.example/realms/lab")
    monkeypatch.setenv("CURVEFM_OIDC_CLIENT_SECRET", "never-shown-secret")
    with pytest.raises(InvalidInput) as refused:
        Settings.from_env()
    assert "single sign-on needs CURVEFM_OIDC_CLIENT_ID too" in refused.value.message
    assert "never-shown-secret" not in refused.value.message
    monkeypatch.setenv("CURVEFM_OIDC_CLIENT_ID", "curvefm")
    settings = Settings.from_env()
    assert settings.sso and "never-shown-secret" not in repr(settings)
    assert settings.oidc_client_secret.get_secret_value() == "never-shown-secret"
    monkeypatch.setenv("CURVEFM_OIDC_ISSUER", "login.uni.example")
    with pytest.raises(InvalidInput, match="CURVEFM_OIDC_ISSUER='login.uni.example' is not valid: an http"):
        Settings.from_env()
