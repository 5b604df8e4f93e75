"""The colour check's task: illuminant estimators trained on synthetic RAW, tested on the
camera's real files (Graphics2RAW, Seo et al. ICCV 2023, Table 2).

- `estimators`: the learned estimators (CNN, moments, histogram);
- `experiment`: the cross-validated experiment over the training-set rows and its controls;
- `content_rows`: the rows with the content model fitted per fold;
- `augmentation`: real files together with synthetic RAW, the recipe chosen on the real files;
- `labelled_curve`: what adding g2r_jax RAW is worth by the number of labelled files;
- `content`: the CG set's content statistics next to the real files';
- `reporting`: the result in words, tables and a plot.

Layer: imports the shared base (`downstream.base`), never the other tasks.
"""
