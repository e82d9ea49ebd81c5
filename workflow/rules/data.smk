# Raw data: copied from $NLDR_DATA_MIRROR or downloaded from a pinned URL, then sha256-verified
# (nldr.datasets.fetch writes to a temporary name and renames only a verified file). No retries: a
# missing or corrupt source, or no network, fails the same way the second time.
#
# Files already present are verified before any job is scheduled (nldr.datasets.verify_present):
# a data file changed after a good run would otherwise make Snakemake rerun, and so first delete the
# outputs of, every job downstream of it, each of which would then fail on the hash.
try:
    verify_present(DATA_DIR)
except DataError as exc:
    raise WorkflowError(f"data check failed before any job ran; results are untouched.\n{exc}")


rule fetch_data:
    output:
        f"{DATA_DIR}/{{relpath}}",
    wildcard_constraints:
        relpath=r"(oil/Data(Trn|Tst|Vdn)(Lbls)?\.txt|nrsfm/(drink|pickup|yoga|stretch|dance)\.mat)",
    params:
        data_dir=lambda wildcards, output: output[0][: -len(wildcards.relpath) - 1],
    conda:
        "../envs/nldr.yaml"
    log:
        f"{RESULTS}/logs/fetch_data/{{relpath}}.log",
    localrule: True
    script:
        "../scripts/fetch_data.py"
