"""A real OpenID Connect provider for the single sign-on tests: pyop (the IdentityPython project's provider library:
discovery, authorization, token and userinfo endpoints, PKCE, RS256-signed ID tokens) in a small Flask app on
loopback, over HTTPS as OpenID Connect requires (a certificate for 127.0.0.1 from a CA the test makes:
:func:`make_certificates`; a client trusts it through ``SSL_CERT_FILE``), whose users sign in through a form.
:func:`start_provider` starts it as a process of its own.

``POST /test/tamper`` ``{"id_token": MODE}`` makes the token endpoint hand out broken ID tokens from then on, as a
faulty or hostile provider would: ``audience`` (issued to another client), ``signature`` (signed by a key the JWKS
does not have, under the published key's id), ``expired``, ``long-subject`` (a ``sub`` past OpenID Connect's 255
characters), or ``none`` (correct again). Nothing else is faked.

Run as ``python oidc_provider.py PORT CERTIFICATE KEY CLIENT_ID CLIENT_SECRET REDIRECT_URI...``.
"""

from __future__ import annotations

import base64
import datetime
import html
import ipaddress
import json
import secrets
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import urlencode

USERS = {
    "ada": {"password": "analytical-engine", "preferred_username": "ada", "email": "ada@uni.example"},
    "grace": {"password": "compiler-1952", "email": "grace.hopper@uni.example"},  # no preferred_username
}
"""The people who can sign in, with the claims the provider gives about them: all in its userinfo,
preferred_username in the ID token too."""
KEY_ID = "test-key-1"
LOGIN_FORM = """<!doctype html><html><head><title>Test identity provider</title></head><body>
<h1>Test identity provider</h1><form method="post" action="/login">
<input type="hidden" name="request" value="{request}">
<label>User <input name="username" id="username"></label>
<label>Password <input name="password" id="password" type="password"></label>
<button type="submit" id="sign-in">Sign in</button></form><p id="error">{error}</p></body></html>"""


def create_app(issuer: str, client_id: str, client_secret: str, redirect_uris: list[str]):
    from Cryptodome.PublicKey import RSA
    from flask import Flask, jsonify, make_response, redirect, request
    from jwkest.jwk import RSAKey
    from oic.oic.message import TokenErrorResponse
    from pyop.authz_state import AuthorizationState
    from pyop.exceptions import InvalidAuthenticationRequest, InvalidClientAuthentication, OAuthError
    from pyop.provider import Provider
    from pyop.subject_identifier import HashBasedSubjectIdentifierFactory
    from pyop.userinfo import Userinfo
    from pyop.util import should_fragment_encode

    signing_key = RSAKey(key=RSA.generate(2048), alg="RS256", kid=KEY_ID)
    configuration = {
        "issuer": issuer,
        "authorization_endpoint": f"{issuer}/authorize",
        "token_endpoint": f"{issuer}/token",
        "userinfo_endpoint": f"{issuer}/userinfo",
        "jwks_uri": f"{issuer}/jwks",
        "scopes_supported": ["openid", "profile", "email"],
        "response_types_supported": ["code"],
        "subject_types_supported": ["public"],
        "token_endpoint_auth_methods_supported": ["client_secret_basic", "client_secret_post"],
        "code_challenge_methods_supported": ["S256"],
    }
    clients = {
        client_id: {
            "client_secret": client_secret,
            "redirect_uris": redirect_uris,
            "response_types": ["code"],
            "token_endpoint_auth_method": "client_secret_basic",
        }
    }
    claims = {name: {k: v for k, v in user.items() if k != "password"} for name, user in USERS.items()}
    state = AuthorizationState(HashBasedSubjectIdentifierFactory(secrets.token_hex(8)))
    provider = Provider(signing_key, configuration, state, clients, Userinfo(claims))
    pending: dict[str, object] = {}  # authentication requests waiting for their user to sign in

    def in_id_token(user: str, client: str) -> dict:
        """preferred_username in the ID token, as Keycloak does (pyop puts scope claims in its userinfo only)."""
        return {k: v for k, v in claims[user].items() if k == "preferred_username"}

    tamper = {"id_token": "none"}
    app = Flask("oidc_provider")

    @app.get("/.well-known/openid-configuration")
    def discovery():
        return jsonify(provider.provider_configuration.to_dict())

    @app.get("/jwks")
    def jwks():
        return jsonify(provider.jwks)

    @app.get("/authorize")
    def authorize():
        try:
            authentication = provider.parse_authentication_request(urlencode(request.args), request.headers)
        except InvalidAuthenticationRequest as exc:
            return make_response(f"bad authentication request: {html.escape(str(exc))}", 400)
        if authentication.get("code_challenge_method") != "S256":
            return make_response("this provider requires PKCE (S256)", 400)
        key = secrets.token_urlsafe(16)
        pending[key] = authentication
        return LOGIN_FORM.format(request=key, error="")

    @app.post("/login")
    def login():
        key, name = request.form.get("request", ""), request.form.get("username", "")
        if key not in pending:
            return make_response("unknown authentication request", 400)
        if USERS.get(name, {}).get("password") != request.form.get("password"):
            return LOGIN_FORM.format(request=html.escape(key), error="wrong user name or password")
        authentication = pending.pop(key)
        answer = provider.authorize(authentication, name)
        return redirect(answer.request(authentication["redirect_uri"], should_fragment_encode(authentication)), 303)

    @app.post("/token")
    def token():
        try:
            answer = provider.handle_token_request(
                request.get_data().decode(), request.headers, extra_id_token_claims=in_id_token
            ).to_dict()
        except InvalidClientAuthentication as exc:
            error = TokenErrorResponse(error="invalid_client", error_description=str(exc))
            return make_response(error.to_json(), 401, {"Content-Type": "application/json"})
        except OAuthError as exc:
            error = TokenErrorResponse(error=exc.oauth_error, error_description=str(exc))
            return make_response(error.to_json(), 400, {"Content-Type": "application/json"})
        if tamper["id_token"] != "none":
            answer["id_token"] = tampered(answer["id_token"], tamper["id_token"], signing_key)
        return jsonify(answer)

    @app.route("/userinfo", methods=["GET", "POST"])
    def userinfo():
        try:
            return jsonify(provider.handle_userinfo_request(request.get_data().decode(), request.headers).to_dict())
        except Exception as exc:  # pyop's bearer token errors
            return make_response(json.dumps({"error": "invalid_token", "error_description": str(exc)}), 401)

    @app.post("/test/tamper")
    def set_tamper():
        tamper["id_token"] = request.get_json()["id_token"]
        return jsonify(tamper)

    return app


def tampered(id_token: str, mode: str, signing_key) -> str:
    """``id_token`` broken as ``mode`` says, signed again (by another key for ``signature``)."""
    from Cryptodome.PublicKey import RSA
    from jwkest.jwk import RSAKey
    from oic.oic.message import IdToken

    payload = id_token.split(".")[1]
    claims = json.loads(base64.urlsafe_b64decode(payload + "=" * (-len(payload) % 4)))
    key = signing_key
    if mode == "audience":
        claims["aud"] = "another-application"
    elif mode == "expired":
        claims["iat"], claims["exp"] = int(time.time()) - 7200, int(time.time()) - 3600
    elif mode == "long-subject":
        claims["sub"] = "x" * 300
    elif mode == "signature":
        key = RSAKey(key=RSA.generate(2048), alg="RS256", kid=KEY_ID)
    return IdToken(**claims).to_jwt([key], "RS256")


@dataclass(frozen=True)
class Certificates:
    ca: Path  # what a client trusts (SSL_CERT_FILE)
    certificate: Path  # the provider's, for 127.0.0.1, signed by the CA
    key: Path


def make_certificates(folder: Path) -> Certificates:
    """A CA and a certificate for 127.0.0.1 that it signed, valid for a day."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

    now = datetime.datetime.now(datetime.UTC)
    ca_key, key = ec.generate_private_key(ec.SECP256R1()), ec.generate_private_key(ec.SECP256R1())
    ca_name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "curvefm test CA")])

    def signed(builder, public_key, extensions):
        builder = builder.issuer_name(ca_name).public_key(public_key).serial_number(x509.random_serial_number())
        builder = builder.not_valid_before(now - datetime.timedelta(minutes=5)).not_valid_after(
            now + datetime.timedelta(days=1)
        )
        for extension, critical in extensions:
            builder = builder.add_extension(extension, critical=critical)
        return builder.sign(ca_key, hashes.SHA256())

    ca = signed(
        x509.CertificateBuilder().subject_name(ca_name),
        ca_key.public_key(),
        [
            (x509.BasicConstraints(ca=True, path_length=0), True),
            (x509.KeyUsage(False, False, False, False, False, True, True, False, False), True),
            (x509.SubjectKeyIdentifier.from_public_key(ca_key.public_key()), False),
        ],
    )
    leaf = signed(
        x509.CertificateBuilder().subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "127.0.0.1")])),
        key.public_key(),
        [
            (x509.SubjectAlternativeName([x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]), False),
            (x509.BasicConstraints(ca=False, path_length=None), True),
            (x509.ExtendedKeyUsage([ExtendedKeyUsageOID.SERVER_AUTH]), False),
            (x509.AuthorityKeyIdentifier.from_issuer_public_key(ca_key.public_key()), False),
        ],
    )
    folder.mkdir(parents=True, exist_ok=True)
    paths = Certificates(folder / "ca.pem", folder / "provider.pem", folder / "provider.key")
    paths.ca.write_bytes(ca.public_bytes(serialization.Encoding.PEM))
    paths.certificate.write_bytes(leaf.public_bytes(serialization.Encoding.PEM))
    paths.key.write_bytes(
        key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption())
    )
    return paths


@dataclass
class OidcProvider:
    """A provider process (:func:`start_provider`), its client's credentials and the CA its certificate is of."""

    issuer: str
    client_id: str
    client_secret: str
    ca: Path
    process: object
    log: Path

    def http(self, **options):
        """An httpx client that trusts the provider's certificate."""
        import ssl

        import httpx

        return httpx.Client(verify=ssl.create_default_context(cafile=str(self.ca)), **options)

    def tamper(self, mode: str) -> None:
        with self.http() as client:
            client.post(f"{self.issuer}/test/tamper", json={"id_token": mode}).raise_for_status()

    def sign_in(self, authorize_url: str, user: str) -> str:
        """Sign ``user`` in at ``authorize_url`` through the form, as a browser would; returns where the provider
        sends the browser back (the callback URL with code and state)."""
        with self.http() as client:
            form = client.get(authorize_url)
            assert form.status_code == 200, form.text
            key = form.text.split('name="request" value="')[1].split('"')[0]
            password = USERS[user]["password"]
            answer = client.post(f"{self.issuer}/login", data={"request": key, "username": user, "password": password})
        assert answer.status_code == 303, answer.text
        return answer.headers["location"]


def start_provider(processes, port: int, redirect_uris: list[str]) -> OidcProvider:
    """A provider process on ``port`` (issuer ``https://127.0.0.1:PORT``) that knows one client, whose sign-ins may
    return to ``redirect_uris``; it answers discovery when this returns."""
    import httpx

    tls = make_certificates(processes.folder / f"oidc-provider-{port}")
    client_id, client_secret = "curvefm-test", "s3cret-" + secrets.token_hex(12)
    args = ["python", __file__, str(port), str(tls.certificate), str(tls.key), client_id, client_secret]
    process = processes.start([*args, *redirect_uris], f"oidc-provider-{port}")
    log = processes.folder / f"oidc-provider-{port}.log"
    provider = OidcProvider(f"https://127.0.0.1:{port}", client_id, client_secret, tls.ca, process, log)
    deadline = time.monotonic() + 60
    with provider.http() as client:
        while time.monotonic() < deadline:
            assert process.poll() is None, log.read_text()[-3000:]
            try:
                if client.get(f"{provider.issuer}/.well-known/openid-configuration").status_code == 200:
                    return provider
            except httpx.TransportError:
                time.sleep(0.1)
    raise AssertionError(f"the OpenID Connect provider on port {port} did not answer within 60 s")


if __name__ == "__main__":
    port, certificate, key, client_id, client_secret, *uris = sys.argv[1:]
    create_app(f"https://127.0.0.1:{port}", client_id, client_secret, uris).run(
        host="127.0.0.1", port=int(port), threaded=True, ssl_context=(certificate, key)
    )
