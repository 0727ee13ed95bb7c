"""What the benchmarks say of a model's own fit: the metrics its fit recorded per material
(on the fit's evaluation pairs), averaged over its collection."""

from __future__ import annotations


def collection_means(model) -> str:
    """Mean SMAPE and cMAE of a network's own collection, from the metrics its fit recorded."""
    met = [m["metrics"] for m in model.material_info if m.get("metrics")]
    if not met:
        return "no recorded metrics"
    return (f"mean SMAPE {sum(x['smape'] for x in met) / len(met):.4f}, "
            f"mean cMAE {sum(x['cmae'] for x in met) / len(met):.5f} over its {len(met)} materials")
