"""The main path of structsearch in Python, as a notebook would run it (``python examples/tutorial.py``).

Simulate a small flight-test campaign, fit the thesis' final lift and drag structures, search the drag grid,
diagnose Van Ingen's drag model, and print what each step gives back. Every step is what a command does
(README: the API beside each command); nothing here writes files.
"""
import structsearch as ss

# `structsearch simulate --scale 0.05`: 5 % of the maneuvers of the default campaign (seed 0)
campaign = ss.simulate(scale=0.05)
print(f"campaign: {len(campaign.maneuvers)} maneuvers, {campaign.data.n_samples} samples")

# `structsearch fit --model CL-VI` and `--model CD-IXr` (a drag candidate fits its lift model CL-VI first)
lift = ss.fit(campaign, "CL-VI", settings=ss.Settings(starts=1))
print(f"{lift.candidate.name}: MSE train {lift.result.mse_train:.4g}, validation {lift.result.mse_validation:.4g}")
drag = ss.fit(campaign, "CD-IXr", settings=ss.Settings(starts=1))
print(f"{drag.candidate.name} on {drag.lift.name}: validation MSE {drag.result.mse_validation:.4g}")
print(drag.summary())

# `structsearch search --grid drag`: no cache directory needed (a temporary one is used)
ranking = ss.search(campaign, "drag", settings=ss.Settings(starts=1, jobs=2))
frame = ranking.to_frame()
print(frame[["grid", "model", "rank", "n_params", "mse_validation", "admissible"]].head(5).to_string(index=False))
print(f"best drag structure: {ranking.best('drag').name}")

# `structsearch diagnose --model CD-I`: where Van Ingen's drag model misses the data, and which effect closes it
diagnosis = ss.diagnose(campaign, "CD-I", settings=ss.Settings(starts=1, jobs=2))
doc = diagnosis.to_dict()
print(f"{doc['baseline']}: final model {doc['final_model']}, explained: {'yes' if doc['explained'] else 'no'}")
