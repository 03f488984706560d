"""Python SDK for the tcfarm render farm: talks only to its HTTP API (proto/openapi.yaml)."""
from tcfarm.client import ApiError, AssetUpload, Client

__version__ = "0.2.0"
__all__ = ["ApiError", "AssetUpload", "Client", "__version__"]
