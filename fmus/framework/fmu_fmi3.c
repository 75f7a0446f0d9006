/* The whole FMU (FMI 3.0 layer, core, model) as one translation unit: what the model description lists
 * for importers that compile the sources. Every internal name is static here (framework.h), so several
 * source FMUs link into one program, each compiled with its own FMI3_FUNCTION_PREFIX. */
#define FMU_SINGLE_UNIT
#define MODEL_DESCRIPTION_TABLES /* the generated variable tables, once for the whole unit */
#include "fmi3_functions.c"
#include "core.c"
#include "stepper.c"
#include "instance.c"
#include "integrators.c"
#include "linear_model.c"
#include "constraints.c"
#include "physics.c"
