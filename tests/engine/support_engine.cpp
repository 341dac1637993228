#include "support_engine.hpp"

#include "engine/store.hpp"

namespace millflow::engine::testing {

Registry testing_registry() {
  Registry registry;
  add_testing(registry);
  return registry;
}

Campaign test_campaign(const std::string& name, nlohmann::json tasks) {
  return Campaign{name,
                  "millflow-test",
                  {{"format", "millflow-test"}, {"name", name}, {"tasks", std::move(tasks)}}};
}

nlohmann::json noted_diamond(int c_value) {
  using nlohmann::json;
  return json::array(
      {{{"id", "a"}, {"kind", "sum"}, {"params", {{"value", 1}, {"artifact", true}}}},
       {{"id", "b"}, {"kind", "sum"}, {"params", {{"value", 2}}}, {"after", {"a"}}},
       {{"id", "c"},
        {"kind", "sum"},
        {"params", {{"value", c_value}, {"note", "c"}}},
        {"after", {"a"}}},
       {{"id", "d"}, {"kind", "sum"}, {"params", {{"value", 4}}}, {"after", {"b", "c"}}}});
}

RunSummary submit(const Campaign& campaign, const std::filesystem::path& db, int jobs,
                  int retries) {
  SubmitOptions options;
  options.run.jobs = jobs;
  options.run.retries = retries;
  return submit_campaign(testing_registry(), campaign, db, options);
}

std::int64_t count(const std::filesystem::path& db, const std::string& sql) {
  auto connection = open_read_only(db);
  auto row = connection.prepare(sql);
  row.step();
  return row.integer(0);
}

nlohmann::json result_of(const std::filesystem::path& db, const std::string& key) {
  auto connection = open_read_only(db);
  return find_result(connection, key).value_or(nlohmann::json());
}

}  // namespace millflow::engine::testing
