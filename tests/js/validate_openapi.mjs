// swagger-parser's validate on an OpenAPI document: dereferences every $ref (files beside it
// included) and checks the result against the OpenAPI schema. Prints "ok" or the error; the exit
// status says which. Usage: node validate_openapi.mjs schemas/openapi.yaml
import SwaggerParser from "@apidevtools/swagger-parser";

try {
  const api = await SwaggerParser.validate(process.argv[2]);
  console.log(`ok: ${api.info.title} ${api.info.version}, ${Object.keys(api.paths).length} paths`);
} catch (e) {
  console.error(String(e.message || e));
  process.exit(1);
}
