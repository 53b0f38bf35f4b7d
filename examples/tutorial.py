"""The main path of structsearch in Python, as a notebook would run it (``python examples/tutorial.py``).

What it shows, on half of the default simulated campaign (24 maneuvers, 19 of them for training; 2 to 5 minutes
on two cores):

1. simulate a flight-test campaign (``structsearch simulate --scale 0.5``);
2. fit the thesis' final lift and drag structures, CL-VI and CD-IXr (``structsearch fit``), and read the drag
   fit's summary: estimates, standard deviations, t-tests and flags. A parameter whose t reference has fewer than
   5 degrees of freedom is flagged "few maneuvers": its interval rests on few maneuvers;
3. search the drag grid (``structsearch search --grid drag``) and name the best admissible structure, or say
   that none is;
4. diagnose Van Ingen's drag model CD-I (``structsearch diagnose --model CD-I``): its gap to the noise floor,
   the moves adopted to close it, and whether the model reached is at the floor.

Why half the campaign (measured on seed 0): on 5 % and 25 % of it (6 and 14 maneuvers) no drag structure was
admissible and nearly every parameter rested on few maneuvers; on 35 % and 40 % some drag structures were, but 6 or
more of CL-VI's 11 parameters and 2 of CD-IXr's 6 still rested on few. Half is the smallest share measured where
drag structures are admissible and CD-IXr has one parameter on few maneuvers, as on the full campaign (46
maneuvers). Each claim printed below is checked on the results before it is printed.
Nothing here writes files (the fits are cached in a temporary directory).
"""
import structsearch as ss
from structsearch.engine.summary import FEW_DOF

SCALE = 0.5
# one start per nonlinear fit (the commands' default is 4): the tutorial's time, not its answers
settings = ss.Settings(starts=1, jobs=2)


def on_few_maneuvers(result: ss.CandidateResult) -> list[str]:
    """The parameters the summary flags "few maneuvers" (a t reference below FEW_DOF degrees of freedom)."""
    return [name for name, dof in result.estimates.reference_dof.items() if dof < FEW_DOF]


def few_words(result: ss.CandidateResult) -> str:
    few = on_few_maneuvers(result)
    return (f"{len(few)} of {len(result.estimates.params)} parameters on few maneuvers"
            + (f" ({', '.join(few)})" if few else ""))


campaign = ss.simulate(scale=SCALE)
n_train = sum(m.split == "train" for m in campaign.maneuvers)
print(f"campaign: {len(campaign.maneuvers)} maneuvers ({n_train} for training), {campaign.data.n_samples} samples")

# a drag candidate fits its lift model (CL-VI) first
lift = ss.fit(campaign, "CL-VI", settings=settings)
print(f"{lift.candidate.name}: MSE train {lift.result.mse_train:.4g}, validation {lift.result.mse_validation:.4g}; "
      f"{few_words(lift.result)}")
drag = ss.fit(campaign, "CD-IXr", settings=settings)
print(f"{drag.candidate.name} on {drag.lift.name}: validation MSE {drag.result.mse_validation:.4g}; "
      f"{few_words(drag.result)}")
print(drag.summary())

# candidates ranked admissible first (identifiable, significant, within their bounds), then by held-out MSE
ranking = ss.search(campaign, "drag", settings=settings)
frame = ranking.to_frame()
print(frame[["grid", "model", "rank", "n_params", "mse_validation", "admissible"]].head(5).to_string(index=False))
best = ranking.best("drag")
if best is not None and best.placement.admissible:
    n_admissible = sum(bool(r.placement.admissible) for r in ranking.grids["drag"] if not r.failed)
    print(f"best admissible drag structure: {best.name} ({best.n_params} parameters, validation MSE "
          f"{best.mse_validation:.4g}; {n_admissible} of {len(ranking.grids['drag'])} admissible); {few_words(best)}")
elif best is not None:
    print(f"no drag structure is admissible on this campaign; the best fitting, {best.name}, is not: "
          + "; ".join(best.placement.reasons))
else:
    print("every drag candidate failed")

# one structure at a time (a beam of one, as the demo's story): the diagnosis' path is one line of moves
diagnosis = ss.diagnose(campaign, "CD-I", settings=settings, beam=1)
adopted = [r.adopted for r in diagnosis.rounds if r.adopted]
gap = diagnosis.mse.validation / diagnosis.noise_floor - 1
print(f"{diagnosis.baseline}: validation MSE {gap:.0%} above the noise floor; adopted: "
      f"{', then '.join(adopted) if adopted else 'no move'}; final model {diagnosis.final_model} is "
      + ("at the floor" if diagnosis.explained else "still above the floor"))
