# Raw data: copied from $NLDR_DATA_MIRROR or downloaded from a pinned URL, then sha256-verified
# (nldr.datasets.fetch writes to a temporary name and renames only a verified file).


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
    retries: 1
    script:
        "../scripts/fetch_data.py"
