/* The importer's side of FMI 2.0 inside a WebAssembly module. An importer hands the FMU its
 * callbacks as C function pointers; in WebAssembly those are entries of the module's own function
 * table, which JavaScript cannot add to, so the importer's callbacks are these few C functions,
 * linked beside the FMU's unchanged sources. The logger formats the message (it is variadic) and
 * hands it to JavaScript through the imported function env.fmi_log. */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

#include "fmi2_api.h"

__attribute__((import_module("env"), import_name("fmi_log"))) void fmi_log(int status, const char *instance,
                                                                           const char *category, const char *message);

static void logger(fmi2ComponentEnvironment environment, fmi2String instance, fmi2Status status, fmi2String category,
                   fmi2String message, ...)
{
    char text[2048];
    va_list arguments;
    (void)environment;
    va_start(arguments, message);
    vsnprintf(text, sizeof text, message, arguments);
    va_end(arguments);
    fmi_log((int)status, instance ? instance : "", category ? category : "", text);
}

static const fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};

/* The callbacks to pass to fmi2Instantiate. */
__attribute__((visibility("default"))) const fmi2CallbackFunctions *importer_callbacks(void) { return &callbacks; }
