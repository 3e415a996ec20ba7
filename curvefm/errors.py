"""The one exception type for errors a user can cause."""


class CurvefmError(Exception):
    """Bad input or an impossible request, with a message that says what was wrong and what to do.

    ``kind`` lets the HTTP layer pick a status code without parsing messages:
    ``"invalid"`` (400/422), ``"not_found"`` (404), ``"conflict"`` (409), ``"too_large"`` (413).
    """

    def __init__(self, message: str, *, kind: str = "invalid"):
        super().__init__(message)
        self.message = message
        self.kind = kind
