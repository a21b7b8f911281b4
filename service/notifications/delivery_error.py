"""The one error a transport raises: the attempt failed, in words; the notifier retries later."""


class DeliveryError(RuntimeError):
    """A message was not accepted (receiver unreachable, refused, timed out); the text says why."""
