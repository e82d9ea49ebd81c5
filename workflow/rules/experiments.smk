# Generic rules over the experiments of nldr.experiments: run one job, gather a table, draw a
# figure, execute a notebook, and one named target per experiment. Nothing here knows a table.


rule run_job:
    input:
        data=lambda w: data_paths(experiment_of(w).data_files(config, job_of(w))),
    output:
        table=f"{RESULTS}/runs/{{experiment}}/{{job}}.csv",
        arrays=f"{RESULTS}/runs/{{experiment}}/{{job}}.npz",
        timings=f"{RESULTS}/timings/{{experiment}}/{{job}}.csv",
        timing_arrays=f"{RESULTS}/timings/{{experiment}}/{{job}}.npz",
    params:
        settings=lambda w: experiment_of(w).job_settings(config),
        job=lambda w: dict(job_of(w).params),
        data_dir=DATA_DIR,
    wildcard_constraints:
        experiment="|".join(EXPERIMENTS),
        job=r"[A-Za-z0-9_.+-]+",
    threads: lambda w: experiment_of(w).threads(config, job_of(w))
    resources:
        mem_mb=lambda w: experiment_of(w).resources(config, job_of(w))["mem_mb"],
        runtime=lambda w: experiment_of(w).resources(config, job_of(w))["runtime"],
        cpus_per_task=lambda w, threads: threads,  # cluster executors (SLURM) request the job's threads
    conda:
        "../envs/nldr.yaml"
    log:
        f"{RESULTS}/logs/run/{{experiment}}/{{job}}.log",
    benchmark:
        f"{RESULTS}/benchmarks/{{experiment}}/{{job}}.tsv"
    script:
        "../scripts/run_job.py"


rule gather_table:
    input:
        runs=lambda w: run_files(w.experiment),
        timings=lambda w: timing_files(w.experiment),
        others=lambda w: [f for other in experiment_of(w).gathers_with for f in run_files(other)],
        other_timings=lambda w: [f for o in experiment_of(w).gathers_with for f in timing_files(o)],
    output:
        csv=f"{RESULTS}/tables/{{experiment}}.csv",
        md=f"{RESULTS}/tables/{{experiment}}.md",
        html=report(
            f"{RESULTS}/tables/{{experiment}}.html",
            caption="../report/caption.rst",
            category="Tables",
            labels={"table": "{experiment}"},
        ),
        tex=f"{RESULTS}/tables/{{experiment}}.tex",
        timings=f"{RESULTS}/timings/{{experiment}}.csv",
    params:
        caption=lambda w: experiment_of(w).caption(config),
    wildcard_constraints:
        experiment="|".join(EXPERIMENTS),
    conda:
        "../envs/nldr.yaml"
    log:
        f"{RESULTS}/logs/gather_table/{{experiment}}.log",
    localrule: True
    script:
        "../scripts/gather_table.py"


rule draw_figure:
    input:
        runs=lambda w: run_files(figure_owner(w.figure)),
        arrays=lambda w: run_files(figure_owner(w.figure), "npz"),
        data=lambda w: data_paths(figure_owner(w.figure).data_files(config)),
    output:
        png=report(
            f"{RESULTS}/figures/{{figure}}.png",
            caption="../report/caption.rst",
            category="Figures",
            labels={"figure": "{figure}"},
        ),
        pdf=f"{RESULTS}/figures/{{figure}}.pdf",
        svg=f"{RESULTS}/figures/{{figure}}.svg",
    params:
        caption=lambda w: figure_owner(w.figure).figure_captions.get(w.figure, ""),
        data_dir=DATA_DIR,
    wildcard_constraints:
        figure="|".join(f for e in EXPERIMENTS.values() for f in e.figures),
    conda:
        "../envs/nldr.yaml"
    log:
        f"{RESULTS}/logs/draw_figure/{{figure}}.log",
    localrule: True
    script:
        "../scripts/draw_figure.py"


# The last step of an experiment's target: its notebook executed (papermill) with this run's files.
rule notebook:
    input:
        notebook=lambda w: str(REPO / "notebooks" / f"{w.notebook}.py"),
        table=lambda w: table_files(NOTEBOOKS[w.notebook])[0],
        figures=lambda w: [figure_path(f) for f in NOTEBOOKS[w.notebook].figures],
        runs=lambda w: run_files(NOTEBOOKS[w.notebook]),
        arrays=lambda w: run_files(NOTEBOOKS[w.notebook], "npz"),
        timings=lambda w: timing_files(NOTEBOOKS[w.notebook]),  # beside the runs (notebook.locate)
        timing_table=lambda w: timing_table(NOTEBOOKS[w.notebook]),
        data=lambda w: data_paths(NOTEBOOKS[w.notebook].data_files(config)),
    output:
        f"{RESULTS}/notebooks/{{notebook}}.ipynb",
    params:
        parameters=lambda w: {
            "settings": NOTEBOOKS[w.notebook].settings(config),
            "data_dir": DATA_DIR,  # relative to the working directory, where the kernel runs
        },
        results=lambda w, output: str(Path(output[0]).parents[1]),  # <results>/notebooks/<name>.ipynb
    wildcard_constraints:
        notebook="|".join(NOTEBOOKS),
    conda:
        "../envs/nldr.yaml"
    log:
        f"{RESULTS}/logs/notebook/{{notebook}}.log",
    localrule: True
    script:
        "../scripts/run_notebook.py"


# `snakemake <experiment>`: one named target per experiment.
for _experiment in EXPERIMENTS.values():

    rule:
        name:
            _experiment.name
        input:
            target_of(_experiment),
        localrule: True


for _figure in [f for e in EXPERIMENTS.values() for f in e.figures]:

    rule:
        name:
            _figure
        input:
            figure_files(_figure),
        localrule: True
