"""Export: ranked critical scenarios -> OpenSCENARIO + OpenDRIVE catalog; esmini runs."""

from sensorgap.export.catalog import export_catalog
from sensorgap.export.generator import CriticalScenarios

__all__ = ["CriticalScenarios", "export_catalog"]
